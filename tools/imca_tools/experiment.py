"""./imca experiment: a grid of training runs, resumable, with tables and plots.

  ./imca experiment --preset paper|edti|headline|frontier|multi_room3|quick [--out DIR] [--jobs N]
  ./imca experiment --grid FILE.json [--out DIR] [--jobs N]
  ./imca experiment --report DIR        (tables and plots of what DIR holds)
  ./imca experiment --status DIR        (each cell: done, running, pending, failed, not run)
  ./imca experiment --preset|--grid ... --backend slurm [--wait]   (one Slurm job array)
  ./imca experiment --preset|--grid ... --backend k8s [--apply]    (a Kubernetes Indexed Job)

Every cell (scenario x reward x credit x permutation x seed x budget) is one
`./imca train` run through the real services, in DIR/cells/<cell>/. A cell
whose summary.json says it reached its budget is skipped, so running the same
command again after Ctrl-C or a crash resumes; an unfinished cell starts over
(each cell is one uninterrupted run). Results: DIR/table.md, DIR/table.csv,
DIR/runs.csv, DIR/curves-<scenario>-<reward>.png, DIR/shares-<scenario>-<reward>.png,
DIR/gifs/<scenario>-<reward>-<method>.gif. See docs/experiments.md.

On a cluster (--backend slurm|k8s, imca_tools.cluster) each task runs one
cell the same way, and submitting again resumes as a local rerun does.

Each cell runs `python3 -m imca_tools.train` (./imca train) in a child
process; its flags are checked beforehand as ./imca train checks them
(imca_tools.plan), without starting anything.
"""
import argparse
import os
import sys

from . import binaries, cluster, options, report
from .binaries import ROOT
from .grid import ExperimentError, cell_id, check_flags, expand, load_grid, load_saved_grid, only, save_grid
from .presets import PRESET_EDITION, presets
from .runner import default_jobs, run_cells


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    p = options.OneLineParser(prog="imca experiment", description=__doc__,
                             formatter_class=argparse.RawDescriptionHelpFormatter)
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--preset", help="a built-in grid (docs/experiments.md; a wrong name lists them)")
    what.add_argument("--grid", metavar="FILE", help="a JSON grid (docs/experiments.md)")
    what.add_argument("--report", metavar="DIR", help="only (re)write the tables and plots of DIR")
    what.add_argument("--status", metavar="DIR", help="the state of each cell of DIR: done, running, pending, "
                                                        "failed (with its last log line), not run")
    what.add_argument("--run-cell", metavar="FILE", help="(a cluster task) run one cell of the submission FILE "
                                                          "into --out: cell --index, else $SLURM_ARRAY_TASK_ID or "
                                                          "$JOB_COMPLETION_INDEX")
    p.add_argument("--out", default="",
                   help=f"results folder (default: results/<preset>-{PRESET_EDITION} or results/<grid name>)")
    p.add_argument("--jobs", type=options.positive_int, default=0,
                   help=f"runs at once (default: cores/2 = {default_jobs()}; on a cluster: no limit but the "
                        "cluster's)")
    p.add_argument("--only", default="", metavar="CELL[,CELL]",
                   help="run (submit) only these cells of the grid (--status names them)")
    p.add_argument("--index", type=int, default=None, help=argparse.SUPPRESS)
    cluster_flags = p.add_argument_group("on a cluster (docs/experiments.md, 'On a cluster')")
    cluster_flags.add_argument("--backend", choices=("local", "slurm", "k8s"), default="local",
                               help="local: child processes here (default); slurm: one job array (sbatch) of "
                                    "the unfinished cells; k8s: an Indexed Job manifest of them")
    cluster_flags.add_argument("--cpus-per-task", type=options.positive_int, default=None,
                               help="cores per cell (default: the grid's resources, else 2)")
    cluster_flags.add_argument("--mem", default="", help="memory per cell, e.g. 4G (default: the grid's, else 4G)")
    cluster_flags.add_argument("--time", default="", help="Slurm time limit per cell, e.g. 2:00:00 (default: "
                                                          "the partition's)")
    cluster_flags.add_argument("--partition", default="", help="Slurm partition (default: the cluster's)")
    cluster_flags.add_argument("--sbatch-arg", action="append", default=[], metavar="ARG",
                               help="passed to sbatch as is, e.g. --sbatch-arg=--qos=long (repeatable)")
    cluster_flags.add_argument("--wait", action="store_true",
                               help="slurm: wait for the array to end, then write the tables")
    cluster_flags.add_argument("--poll-seconds", type=float, default=10.0, help=argparse.SUPPRESS)
    cluster_flags.add_argument("--image", default="", help="k8s: the image (deploy/Dockerfile; default imca:latest)")
    cluster_flags.add_argument("--claim", default="",
                               help="k8s: the ReadWriteMany PersistentVolumeClaim that holds the results "
                                    "(default imca-results)")
    cluster_flags.add_argument("--k8s-out", default="", help="k8s: the results folder in the pods "
                                                             "(default: /results/<basename of --out>)")
    cluster_flags.add_argument("--apply", action="store_true", help="k8s: kubectl apply the manifest")
    args = p.parse_args(options.dashed(argv))
    try:
        if args.preset and args.preset not in presets():
            p.error(f"argument --preset: '{args.preset}' is not one of {', '.join(sorted(presets()))}")
    except binaries.LaunchError as error:
        p.error(str(error))
    running = bool(args.preset or args.grid)
    for flag, backends in (("cpus_per_task", ("slurm", "k8s")), ("mem", ("slurm", "k8s")), ("time", ("slurm",)),
                           ("partition", ("slurm",)), ("sbatch_arg", ("slurm",)), ("wait", ("slurm",)),
                           ("apply", ("k8s",)), ("k8s_out", ("k8s",)), ("image", ("k8s",)), ("claim", ("k8s",))):
        if getattr(args, flag) and not (running and args.backend in backends):
            p.error(f"argument --{flag.replace('_', '-')}: only with --preset or --grid and --backend "
                    + " or ".join(backends))
    if args.backend != "local" and not running:
        p.error("argument --backend: only with --preset or --grid")
    if args.index is not None and not args.run_cell:
        p.error("argument --index: only with --run-cell")
    if args.only and not running:
        p.error("argument --only: only with --preset or --grid")
    if args.poll_seconds <= 0:
        p.error("argument --poll-seconds: must be > 0")
    args.image = args.image or "imca:latest"
    args.claim = args.claim or "imca-results"

    try:
        if args.run_cell:
            if not args.out:
                p.error("argument --run-cell: needs --out (the results folder)")
            return cluster.run_cell(args.run_cell, args.index, os.path.abspath(args.out))
        if args.report or args.status:
            out = os.path.abspath(args.report or args.status)
            grid = load_saved_grid(out, "--report" if args.report else "--status")
        else:
            if args.preset:
                grid = {"name": args.preset, "description": presets()[args.preset]["description"],
                        "entries": presets()[args.preset]["entries"]}
            else:
                grid = load_grid(args.grid)
            default_out = f"{args.preset}-{PRESET_EDITION}" if args.preset else grid["name"]
            out = os.path.abspath(args.out or os.path.join(ROOT, "results", default_out))
        cells = expand(grid["entries"], args.grid or args.preset or "grid.json")
        if args.status:
            return cluster.print_status(out, cells)
        check_flags(cells)
        if args.backend != "local":
            cluster.check(args, grid)  # Before anything is written.
        os.makedirs(out, exist_ok=True)
        failed = 0
        complete = True
        if not args.report:
            save_grid(out, grid)
            if args.backend != "local":
                code = cluster.submit(args, grid, cells, out)
                if not args.wait:
                    return code
            else:
                complete, failed = run_cells(only(cells, args.only), out, args.jobs or default_jobs())
        results = report.write_grid(out, cells)
        if args.wait:
            failed = sum(1 for c in only(cells, args.only) if results[cell_id(c)] is None)
    except ExperimentError as error:
        print(f"imca experiment: {error}", file=sys.stderr)
        return 2
    if not complete:
        print("imca experiment: interrupted; the same command resumes", file=sys.stderr)
        return 130
    print(f"imca experiment: table {os.path.join(out, 'table.md')}", file=sys.stderr)
    if failed:
        print(f"imca experiment: {failed} cells failed (their train.log says why; --status lists them); the same "
              f"command retries them", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
