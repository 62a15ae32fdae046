"""./imca bench: benchmarks run by hand, one module per part (speed, env,
reward, credit, learn, soak, drill, python), what several share in common.py,
and the command line (the parts listed) in __main__.py."""
