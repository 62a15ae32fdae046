"""What several of ./imca bench's parts share: a run of ./imca train and its
steady rate, a benchmark binary's run, and the steps to 90% success."""
import csv
import json
import os
import shutil
import statistics
import subprocess
import sys

from .. import binaries, runs
from ..binaries import BIN

LAUNCH = binaries.module_argv("train")


def train(out, extra):
    if os.path.exists(out):
        shutil.rmtree(out)  # An unfinished run starts over.
    r = subprocess.run(LAUNCH + ["--out", out, "--quiet"] + extra, capture_output=True, text=True,
                       env=binaries.module_env())
    if r.returncode != 0:
        sys.exit(f"imca bench: training failed: {r.stderr.strip().splitlines()[-1] if r.stderr.strip() else r.returncode}")
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    with open(os.path.join(out, "metrics.csv")) as f:
        rows = list(csv.DictReader(f))
    return summary, rows


def steady_rate(rows):
    """Env steps/s over the second half of a run (start-up excluded)."""
    mid = rows[len(rows) // 2]
    last = rows[-1]
    return (int(last["env_steps"]) - int(mid["env_steps"])) / (float(last["wall_seconds"]) - float(mid["wall_seconds"]))


def median_reached(values):
    """Median over all seeds with not-reached (None) as infinitely late; None if that is the median."""
    ordered = sorted(float("inf") if v is None else v for v in values)
    if not ordered:
        return None
    m = statistics.median(ordered)
    return None if m == float("inf") else m


def to_90(rows, key):
    """(env steps, wall seconds) at the first row with `key` >= 0.9, or (None, None)."""
    row = runs.first_reaching(rows, 0.9, key)
    return (int(row["env_steps"]), float(row["wall_seconds"])) if row else (None, None)


def millions(steps):
    """Env steps in millions ('1.25M'), or '-' when not reached (None)."""
    return "-" if steps is None else f"{steps / 1e6:.2f}M"


def run_binary(name, *args):
    """The completed run of the binary `name` (in BIN) with `args`, its output
    captured as text."""
    return subprocess.run([os.path.join(BIN, name)] + [str(a) for a in args], capture_output=True, text=True)


def exit_if_failed(r, name):
    """Exits with the stderr of the binary `name` that ran as `r`, if it failed."""
    if r.returncode != 0:
        sys.exit(f"imca bench: {name} failed: {r.stderr.strip()}")
