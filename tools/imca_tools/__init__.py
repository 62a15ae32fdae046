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

Command lines, each a thin `main()` run as `python3 -m imca_tools.<name>`:
    train           ./imca train
    experiment      ./imca experiment
    report          ./imca experiment --report DIR (tables and plots)
    bench           ./imca bench
    container_test  ./imca deploy-test
    doc_tables      ./imca doc-tables (ctest doc_tables_check: --check)

The package holds no training policy: what it does not get from the user it
asks the binaries. Its own settings are the launcher's (restart cap, stall
limit, timeouts, ports) and the benchmarks' and experiment presets' workloads.
"""
