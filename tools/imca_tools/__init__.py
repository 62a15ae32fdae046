"""The Python front ends behind ./imca, as one package (PYTHONPATH=tools).

Libraries, by job:
    binaries    where the binaries are and what they say of themselves
                (`--list`, `--print_config`): the one home of every default
    options     the ./imca train flag vocabulary: each option and the binary
                flags it sets; --door_timer read as --door-timer
    plan        ./imca train's flags -> each program's flags and config.json,
                checked by the binaries before anything starts
    supervisor  the process supervisor (the loopback stand-in for Compose's
                and Kubernetes' restart policies)
    runs        run folders: metrics.csv, status files, summary.json, steps
                to a success rate
    grid        an experiment grid: its entries expanded into cells, each
                cell's name and ./imca train flags, grid.json
    presets     the built-in grids (--preset)
    runner      a grid's cells run: finished or refused, locked, started,
                and the local runner (--jobs at a time)
    cluster     the same cells as a Slurm job array or a Kubernetes
                Indexed Job, and a cluster task's one cell
    stats       IQM, stratified bootstrap intervals, performance profiles

Command lines, each a thin `main()` run as `python3 -m imca_tools.<name>`:
    train           ./imca train
    experiment      ./imca experiment
    report          ./imca experiment --report DIR (tables and plots)
    bench           ./imca bench (a package: one module per benchmark)
    doc_tables      ./imca doc-tables (ctest doc_tables_check: --check)
    same_run        whether two run folders hold the same run
    pack            a grid's finished cells in one archive small enough to
                    commit

System tests are in tests/ (container_test.py is ./imca deploy-test).

The package holds no training policy: what it does not get from the user it
asks the binaries. Its own settings are the launcher's (restart cap, stall
limit, timeouts, ports) and the benchmarks' and experiment presets' workloads.
"""
