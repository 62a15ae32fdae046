"""Whether two run folders hold the same training, byte for byte: what
--deterministic promises (docs/learner.md, "Deterministic runs").

    python3 -m imca_tools.same_run RUN_A RUN_B

compares metrics.csv without its wall-clock columns, policy.pb, the reward
snapshot (a count snapshot without its journal line, whose epoch counts the
periodic snapshots taken: every --snapshot-every seconds), and the state
(.pt) and metadata (.meta, without the wall clock and the actors'
incarnations, which each process draws so that a restarted actor is never
taken for its predecessor) of every checkpoint both runs kept, the final
one included (checkpoints are also taken every --checkpoint-seconds, so
which ones a run keeps depends on time). Prints a sha256 per file and run,
and exits 1 on any difference. Runs whose servers ran other CPU kernels
(summary.json's or the status files' "kernels") are not expected to match:
it says so first, as it says when they ran other builds of a program
(config.json's "binaries").
"""
import csv
import hashlib
import io
import os
import re
import sys

from . import binaries
from . import runs


def wall_clock_columns():
    """metrics.csv's columns that measure time, not training (the learner's
    column table says which, `learner --list`)."""
    return {c["name"] for c in binaries.facts()["metrics_columns"] if c["wall_clock"]}


def metrics_without_wall(path):
    wall = wall_clock_columns()
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    keep = [i for i, name in enumerate(rows[0]) if name not in wall] if rows else []
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerows([row[i] for i in keep] for row in rows)
    return out.getvalue().encode()


def meta_without_process(path):
    with open(path) as f:
        text = f.read()
    return re.sub(r"^\s*(wall_seconds|incarnation): .*\n", "", text, flags=re.M).encode()


def snapshot_without_journal(data):
    """A count snapshot (a tag line, then "journal <epoch> <transitions>",
    then the tables) without its journal line; other snapshots as they are."""
    lines = data.split(b"\n", 2)
    if len(lines) == 3 and lines[1].startswith(b"journal "):
        return lines[0] + b"\n" + lines[2]
    return data


def compared_files(run_dir):
    """{name: bytes compared} of a run folder, and the name of its final
    checkpoint's state (or None)."""
    files = {"metrics.csv (no wall columns)": metrics_without_wall(os.path.join(run_dir, "metrics.csv"))}
    path = os.path.join(run_dir, "policy.pb")
    if os.path.exists(path):
        with open(path, "rb") as f:
            files["policy.pb"] = f.read()
    path = os.path.join(run_dir, "reward_snapshot.bin")
    if os.path.exists(path):
        with open(path, "rb") as f:
            files["reward_snapshot.bin (no journal line)"] = snapshot_without_journal(f.read())
    checkpoints = os.path.join(run_dir, "checkpoints")
    final = None
    for name in sorted(os.listdir(checkpoints)) if os.path.isdir(checkpoints) else []:
        path = os.path.join(checkpoints, name)
        if name.endswith(".pt"):
            with open(path, "rb") as f:
                files["checkpoints/" + name] = f.read()
            final = "checkpoints/" + name  # Names sort by version.
        elif name.endswith(".meta"):
            files["checkpoints/" + name + " (no wall clock, incarnations)"] = meta_without_process(path)
    return files, final


def differences(run_a, run_b):
    """[(file, sha256 in a or None, sha256 in b or None)] for every compared
    file, and whether all are equal. A checkpoint only one run kept is left
    out, unless it is that run's final one."""
    (a, final_a), (b, final_b) = compared_files(run_a), compared_files(run_b)
    finals = {name[:-len(".pt")] for name in (final_a, final_b) if name}
    for name in set(a) ^ set(b):
        if name.startswith("checkpoints/") and not any(name.startswith(stem + ".") for stem in finals):
            a.pop(name, None)
            b.pop(name, None)
    if not finals:
        a["checkpoints/ (a final checkpoint)"] = b["checkpoints/ (a final checkpoint)"] = None
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
    try:
        rows, same = differences(*argv)
    except binaries.LaunchError as e:
        print(f"imca same_run: {e}", file=sys.stderr)
        return 2
    ran = [(runs.read_json(os.path.join(run, "summary.json")) or {}).get("kernels") or runs.kernels(run)
           for run in argv]
    if any(ran[0][server] != ran[1][server] for server in ran[0].keys() & ran[1].keys()):
        print(f"imca same_run: the runs ran other CPU kernels ({ran[0]} against {ran[1]}); a deterministic "
              "run replays only on the same (docs/learner.md, \"Deterministic runs\")")
    configs = [runs.read_json(os.path.join(run, "config.json")) or {} for run in argv]
    built = [config.get("binaries") or {} for config in configs]
    if other := sorted(p for p in built[0].keys() & built[1].keys() if built[0][p] != built[1][p]):
        print(f"imca same_run: the runs ran other builds of {', '.join(other)} (config.json's binaries); a change "
              "of code may change the numbers")
    for run, config in zip(argv, configs):
        if config.get("binaries_earlier"):
            print(f"imca same_run: {run} was resumed on another build than it ran before (config.json's "
                  "binaries_earlier)")
    for name, x, y in rows:
        print(f"{'same' if x == y else 'DIFFERENT'}  {name}  {x or '(missing)'}  {y or '(missing)'}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
