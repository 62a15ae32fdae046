"""Run folders: what ./imca train leaves (docs/usage.md, "What a run leaves")
and how the tools read and write it: metrics.csv, credit_trace.csv, the
status files, summary.json (written last: a run folder with one is
complete), steps to a success rate.
"""
import csv
import json
import os

from . import binaries


# What a run folder from before the learner ablation (docs/benchmarks.md,
# "Sample efficiency against the reference MAPPO") ran with when its
# config.json does not record the setting: history, not a default (today's
# are the binaries'). ./imca train --resume of such a folder resumes it as it
# ran; ./imca bench speed measures them as "v1 defaults".
V1_DEFAULTS = {"sync": False, "batch_steps": 8192, "unroll_length": 64, "separate_optimizers": False, "lr": 5e-4}


def read_json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def read_config(run_dir):
    """<run_dir>/config.json as the run ran: settings a run from before a
    default changed did not record (or recorded as None: the binary's default
    then, for MAPPO: another algorithm records None for the settings it does
    not have) are filled with what it ran with (V1_DEFAULTS; MAPPO before
    --algo). OSError or ValueError if there is none."""
    with open(os.path.join(run_dir, "config.json"), errors="backslashreplace") as f:
        saved = json.load(f)
    if not isinstance(saved, dict):
        raise ValueError(f"a JSON {type(saved).__name__}, not an object")
    mappo = saved.get("algo", "mappo") == "mappo"
    for key, old in V1_DEFAULTS.items():
        if key not in saved or (saved[key] is None and mappo):
            saved[key] = old
    saved.setdefault("algo", "mappo")  # Runs from before --algo trained MAPPO.
    return saved


def read_metrics(path):
    """The rows of a CSV file (metrics.csv, logs/trained_unrolls.csv) as
    dicts; none if there is no such file yet."""
    try:
        with open(path) as f:
            return list(csv.DictReader(f))
    except OSError:
        return []


def read_trace(run_dir):
    """credit_trace.csv (actor-0's per-step credit; no rows if absent)."""
    return read_metrics(os.path.join(run_dir, "credit_trace.csv"))


def fmt_duration(seconds):
    """A duration as the progress lines show it (an ETA): 1h05m, 3m07s."""
    seconds = int(max(seconds, 0))
    if seconds >= 3600:
        return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m"
    return f"{seconds // 60}m{seconds % 60:02d}s"


# A success rate counts towards "steps to X%" only once it is over a full
# window of episodes (the learner's LearnerConfig::metrics_window): early on
# the episodes that end first are the short, successful ones, so a rate over
# the first few is biased upwards. Runs written before the learner reported
# the window have no such column and are read as before.
WINDOW_COLUMN = {"success_rate": "success_episodes", "train_success_rate": "train_success_episodes"}


def first_reaching(rows, threshold, key="success_rate"):
    """The first metrics row whose `key` is >= threshold over a full window (None if none)."""
    window = WINDOW_COLUMN.get(key)
    for row in rows:
        if window in row and int(row[window]) < binaries.facts()["success_window"]:
            continue
        if float(row[key]) >= threshold:
            return row
    return None


def steps_to(rows, threshold, key="success_rate"):
    """env_steps of first_reaching (None if never)."""
    row = first_reaching(rows, threshold, key)
    return int(row["env_steps"]) if row else None


def wall_to(rows, threshold, key="success_rate"):
    """wall_seconds of first_reaching (None if never): training's own clock,
    earlier runs of a resumed one included."""
    row = first_reaching(rows, threshold, key)
    return float(row["wall_seconds"]) if row else None


def finished_summary(run_dir, budget):
    """summary.json of a run that reached `budget` env steps uninterrupted, else None."""
    try:
        with open(os.path.join(run_dir, "summary.json")) as f:
            summary = json.load(f)
    except (OSError, ValueError):
        return None
    if summary.get("interrupted") or summary.get("env_steps", 0) < budget:
        return None
    return summary


def write_summary(run_dir, config, rows, interrupted):
    """summary.json from the metrics rows and the run's config.json."""
    last = rows[-1] if rows else None
    summary = {
        "env_steps": int(last["env_steps"]) if last else 0,
        "wall_seconds": float(last["wall_seconds"]) if last else 0.0,
        "env_steps_per_sec": float(last["env_steps_per_sec"]) if last else 0.0,
        "final_success_rate": float(last["success_rate"]) if last else 0.0,
        "final_train_success_rate": float(last["train_success_rate"]) if last else 0.0,
        "final_episode_return": float(last["episode_return"]) if last else 0.0,
        "steps_to_80pct_success": steps_to(rows, 0.8),
        "steps_to_90pct_success": steps_to(rows, 0.9),
        "wall_to_90pct_success": wall_to(rows, 0.9),
        # Over the last 200 training episodes, as marlbenchmark/on-policy
        # reports success (the evaluation window lags: docs/benchmarks.md).
        "steps_to_80pct_train_success": steps_to(rows, 0.8, "train_success_rate"),
        "steps_to_90pct_train_success": steps_to(rows, 0.9, "train_success_rate"),
        "iterations": len(rows),
        "interrupted": interrupted,
        "scenario": config["scenario"], "reward": config["reward"], "credit": config["credit"],
        "permutation": config["permutation"], "seed": config["seed"],
        # Restarts of each process by the supervisor (logs/restarts.csv says why).
        "restarts": config.get("restarts", {}),
        "kernels": kernels(run_dir),
        # {program: sha256} of the binaries the run executed (train.pin_binaries),
        # and those of its parts before a resume on another build.
        "binaries": config.get("binaries", {}),
        **({"binaries_earlier": config["binaries_earlier"]} if config.get("binaries_earlier") else {}),
    }
    write_json_atomically(os.path.join(run_dir, "summary.json"), summary)
    return summary


# The servers whose numerics a run's CPU kernels decide.
KERNEL_SERVERS = ("learner", "reward_server")


def kernels(run_dir):
    """{server: the CPU kernels its numerics ran} from the run's status files,
    "aten=avx2 openblas=SkylakeX" (nn::KernelsInUse): a deterministic run
    replays where these are the same (docs/learner.md, "Deterministic
    runs"). A server whose status file does not say is left out."""
    found = {}
    for name in KERNEL_SERVERS:
        status = read_json(os.path.join(run_dir, "logs", name + ".status.json")) or {}
        if status.get("kernels"):
            found[name] = status["kernels"]
    return found


def write_json_atomically(path, value):
    """A file a crash leaves old or new, never half (as common/base/atomic_file.h)."""
    with open(path + ".tmp", "w") as f:
        json.dump(value, f, indent=2)
        f.flush()
        os.fsync(f.fileno())
    os.replace(path + ".tmp", path)
    fd = os.open(os.path.dirname(path) or ".", os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)

