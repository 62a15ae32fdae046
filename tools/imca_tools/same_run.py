"""Whether two run folders hold the same training, byte for byte: what
--deterministic promises (docs/learner.md, "Deterministic runs").

    python3 -m imca_tools.same_run RUN_A RUN_B

compares metrics.csv without its wall-clock columns, policy.pb, the reward
snapshot, every checkpoint's state (.pt) and its metadata (.meta) without
the wall clock and the actors' incarnations (each process draws its own, so
that a restarted actor is never taken for its predecessor). Prints a sha256
per file and run, and exits 1 on any difference.
"""
import csv
import hashlib
import io
import os
import re
import sys


def is_wall_column(name):
    """metrics.csv's columns that measure time, not training."""
    return name in ("wall_seconds", "env_steps_per_sec") or name.startswith("ms_")


def metrics_without_wall(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    keep = [i for i, name in enumerate(rows[0]) if not is_wall_column(name)] if rows else []
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerows([row[i] for i in keep] for row in rows)
    return out.getvalue().encode()


def meta_without_process(path):
    with open(path) as f:
        text = f.read()
    return re.sub(r"^\s*(wall_seconds|incarnation): .*\n", "", text, flags=re.M).encode()


def compared_files(run_dir):
    """{name: bytes compared} of a run folder."""
    files = {"metrics.csv (no wall columns)": metrics_without_wall(os.path.join(run_dir, "metrics.csv"))}
    for name in ("policy.pb", "reward_snapshot.bin"):
        path = os.path.join(run_dir, name)
        if os.path.exists(path):
            with open(path, "rb") as f:
                files[name] = f.read()
    checkpoints = os.path.join(run_dir, "checkpoints")
    for name in sorted(os.listdir(checkpoints)) if os.path.isdir(checkpoints) else []:
        path = os.path.join(checkpoints, name)
        if name.endswith(".pt"):
            with open(path, "rb") as f:
                files["checkpoints/" + name] = f.read()
        elif name.endswith(".meta"):
            files["checkpoints/" + name + " (no wall clock, incarnations)"] = meta_without_process(path)
    return files


def differences(run_a, run_b):
    """[(file, sha256 in a or None, sha256 in b or None)] for every compared
    file, and whether all are equal."""
    a, b = compared_files(run_a), compared_files(run_b)
    digest = lambda data: hashlib.sha256(data).hexdigest() if data is not None else None
    rows = [(name, digest(a.get(name)), digest(b.get(name))) for name in sorted(set(a) | set(b))]
    return rows, all(x == y and x is not None for _, x, y in rows)


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print("usage: python3 -m imca_tools.same_run RUN_A RUN_B", file=sys.stderr)
        return 2
    for run in argv:
        if not os.path.isfile(os.path.join(run, "metrics.csv")):
            print(f"imca same_run: '{run}' holds no run (no metrics.csv)", file=sys.stderr)
            return 2
    rows, same = differences(*argv)
    for name, x, y in rows:
        print(f"{'same' if x == y else 'DIFFERENT'}  {name}  {x or '(missing)'}  {y or '(missing)'}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
