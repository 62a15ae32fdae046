"""Running a grid's cells: which are finished (their summary.json) or
must be refused (a finished cell run with other settings, a deterministic
cell on other CPU kernels than the grid's), a cell's lock and its
./imca train child process, and the local runner that keeps --jobs of them
going (a cluster task runs one cell with the same parts: imca_tools.cluster).
"""
import contextlib
import fcntl
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time

from . import binaries, plan, runs
from .grid import ExperimentError, cell_dir, cell_id, deterministic, train_argv, train_flags


def finished(run_dir, cell):
    return runs.finished_summary(run_dir, cell["steps"])


# config.json keys that name where and how a run was launched, not what it trained.
UNCOMPARED_SETTINGS = {"out", "resume", "quiet", "reward_port", "learner_port", "metrics_port", "secure",
                       "map", "max_restarts", "stall_seconds",
                       "checkpoint_seconds", "snapshot_every", "given", "resolved", "actor_score_delays_ms",
                       "score_delays"}


def settings_conflict(run_dir, cell):
    """A one-line description of the first setting in which a finished cell's
    config.json differs from what ./imca train would now use for it (its
    defaults changed since), or None (config_conflict)."""
    return config_conflict(run_dir, train_flags(cell, run_dir))


def config_conflict(run_dir, argv):
    """A one-line description of the first setting in which the finished run
    in `run_dir` (its config.json) differs from what `./imca train ARGV` would
    now use, or None. Settings the old run did not record, and those that
    name where and how it ran (UNCOMPARED_SETTINGS), are not compared.
    Raises ValueError with ./imca train's one-line message if ARGV is refused.
    Shared by ./imca experiment and ./imca bench learn, which both resume."""
    try:
        with open(os.path.join(run_dir, "config.json")) as f:
            saved = json.load(f)
    except (OSError, ValueError):
        return None
    captured = io.StringIO()
    try:
        with contextlib.redirect_stderr(captured):
            now = vars(plan.parse_args(argv))
    except SystemExit:
        raise ValueError(captured.getvalue().strip() or "./imca train refuses the flags")
    for key in sorted(set(saved) & set(now) - UNCOMPARED_SETTINGS):
        if saved[key] != now[key]:
            return f"{key} {saved[key]!r} where ./imca train now uses {now[key]!r}"
    return None


def unfinished_cells(cells, out):
    """The (cell, run folder) of each cell not finished in `out`. Raises
    ExperimentError for a finished cell whose config.json differs from what
    ./imca train would now use (resuming would put the results of two
    different configurations in one table)."""
    todo = []
    for cell in cells:
        run_dir = cell_dir(out, cell)
        if not finished(run_dir, cell):
            todo.append((cell, run_dir))
        elif conflict := settings_conflict(run_dir, cell):
            raise ExperimentError(f"{run_dir} was run with {conflict} (its defaults changed since); "
                                  "use another --out, or --report to redraw the old results")
    return todo


def kernels_file(out):
    return os.path.join(out, "kernels.json")


def grid_kernels(out):
    """({server: kernels}, cell id): the CPU kernels the grid in OUT runs its
    deterministic cells on, and the cell that set them: OUT/kernels.json
    (record_kernels), else the first finished deterministic cell's
    summary.json that names them (grids from before kernels.json), else
    ({}, None). Read from the cells' own files, so a cluster task whose OUT
    holds no grid.json reads the same."""
    recorded = runs.read_json(kernels_file(out))
    if isinstance(recorded, dict) and isinstance(recorded.get("kernels"), dict):
        return recorded["kernels"], recorded.get("cell")
    cells = os.path.join(out, "cells")
    for name in sorted(os.listdir(cells)) if os.path.isdir(cells) else []:
        config = runs.read_json(os.path.join(cells, name, "config.json")) or {}
        summary = runs.finished_summary(os.path.join(cells, name), config.get("steps", float("inf"))) or {}
        if config.get("deterministic") and summary.get("kernels"):
            return summary["kernels"], name
    return {}, None


def record_kernels(out, ran, cell):
    """Makes `ran` ({server: kernels}, every server named) the grid's kernels
    unless OUT/kernels.json exists: it is created whole or not at all, and of
    two processes (cluster tasks) the first wins."""
    tmp = f"{kernels_file(out)}.{os.getpid()}.tmp"
    runs.write_json_atomically(tmp, {"kernels": ran, "cell": cell_id(cell)})
    try:
        os.link(tmp, kernels_file(out))  # Fails if it exists: the first writer wins.
    except FileExistsError:
        pass
    finally:
        os.remove(tmp)


def check_kernels(out, cell, run_dir):
    """(conflict, settled) for a running deterministic cell: settled once its
    servers have all named their CPU kernels (the first cell to do so in a
    grid without kernels sets the grid's); conflict, a one-line description
    of the first server that runs other kernels than the grid's, else None
    (the caller stops the cell, then note_refusal). A deterministic run
    replays only on the kernels it ran (docs/learner.md, "Deterministic
    runs"): cells on other kernels would sit in one table with the others as
    if they were replays of one machine."""
    ran = runs.kernels(run_dir)
    settled = set(ran) == set(runs.KERNEL_SERVERS)
    reference, where = grid_kernels(out)
    if not reference and settled:
        record_kernels(out, ran, cell)
        reference, where = grid_kernels(out)  # This cell's, or another's that won.
    for server in sorted(ran.keys() & reference.keys()):
        if ran[server] != reference[server]:
            return (f"{cell_id(cell)}'s {server} runs '{ran[server]}' where the grid's cells run "
                    f"'{reference[server]}' (set by {where}); set OPENBLAS_CORETYPE / ATEN_CPU_CAPABILITY to "
                    f"theirs (docs/learner.md, 'Deterministic runs') or use another --out"), settled
    return None, settled


def note_refusal(run_dir, why):
    """Appends why a cell was stopped to its train.log, once it has stopped:
    its last line, which --status shows."""
    with open(os.path.join(run_dir, "train.log"), "a") as log:
        print(f"imca experiment: {why}", file=log)


def default_jobs():
    # One run keeps about two cores busy (the learner, the actors and the
    # reward server); more runs than cores/2 slow every run down.
    return max(1, (os.cpu_count() or 2) // 2)


def lock_cell(out, cell):
    """An open lock file that holds `cell` of OUT for this process (flock:
    released when the file is closed or the process ends, however), or None
    if another process (a local grid, a cluster task) holds it."""
    os.makedirs(os.path.join(out, "cells"), exist_ok=True)
    lock = open(os.path.join(out, "cells", f".{cell_id(cell)}.lock"), "w")
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        lock.close()
        return None
    return lock


def start_cell(cell, run_dir):
    """Starts a cell's ./imca train run in `run_dir` (emptied first: an
    unfinished cell starts over), its output in run_dir/train.log; the
    child's Popen. Local grids and cluster tasks (cluster.run_cell) both."""
    if os.path.exists(run_dir):
        shutil.rmtree(run_dir)
    os.makedirs(run_dir)
    with open(os.path.join(run_dir, "train.log"), "w") as log:
        return subprocess.Popen(train_argv(cell, run_dir), stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True, env=binaries.module_env())


def run_cells(cells, out, jobs):
    """Runs the unfinished cells, `jobs` at a time. Returns (False if
    interrupted, cells failed). Raises ExperimentError, once the running cells
    are stopped, when a deterministic cell runs other CPU kernels than the
    grid's (check_kernels)."""
    todo = unfinished_cells(cells, out)
    done_before = len(cells) - len(todo)
    print(f"imca experiment: {len(cells)} cells, {done_before} already finished, {len(todo)} to run, "
          f"{jobs} at a time; results in {out}", file=sys.stderr, flush=True)
    running = []  # (cell, run_dir, Popen, start time, lock file)
    unchecked = set()  # run folders of deterministic cells whose kernels are not yet all compared
    refused = []
    stop = []
    old_int = signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    old_term = signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    started = time.time()
    completed = 0
    failures = []
    try:
        while (todo or running) and not stop:
            while todo and len(running) < jobs and not stop:
                cell, run_dir = todo.pop(0)
                lock = lock_cell(out, cell)
                if lock is None:
                    failures.append((cell_id(cell), "it is running in another process (a cluster task?)"))
                    continue
                running.append((cell, run_dir, start_cell(cell, run_dir), time.time(), lock))
                if deterministic(cell):
                    unchecked.add(run_dir)
            time.sleep(0.5)
            for entry in list(running):
                cell, run_dir, proc, t0, lock = entry
                if run_dir in unchecked:
                    conflict, settled = check_kernels(out, cell, run_dir)
                    if conflict:
                        refused.append((run_dir, conflict))
                        stop.append(1)
                        break
                    if settled:
                        unchecked.discard(run_dir)
                if proc.poll() is None:
                    continue
                running.remove(entry)
                unchecked.discard(run_dir)
                lock.close()
                completed += 1
                summary = finished(run_dir, cell)
                if summary is None:
                    failures.append((cell_id(cell), last_line(os.path.join(run_dir, "train.log"))))
                    status = "FAILED"
                else:
                    status = f"success {summary['final_success_rate']:.0%}"
                elapsed = time.time() - started
                left = len(todo) + len(running)
                eta = elapsed / completed * left if completed else 0
                print(f"[{done_before + completed}/{len(cells)}] {cell_id(cell)}: {status} "
                      f"({time.time() - t0:.0f} s); ETA {runs.fmt_duration(eta)}", file=sys.stderr, flush=True)
    finally:
        for _, _, proc, _, _ in running:
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)  # ./imca train stops its services in order.
        for _, run_dir, proc, _, _ in running:
            try:
                # ./imca train stops actors, learner and reward server with
                # bounded waits (at most 270 s in all).
                proc.wait(timeout=330)
            except subprocess.TimeoutExpired:
                proc.kill()
                print(f"imca experiment: {run_dir} did not stop in 330 s; its services may still run "
                      f"(logs/ names them)", file=sys.stderr)
        signal.signal(signal.SIGINT, old_int)
        signal.signal(signal.SIGTERM, old_term)
    if refused:
        note_refusal(*refused[0])
        raise ExperimentError(refused[0][1])
    for cid, line in failures:
        print(f"imca experiment: cell {cid} failed: {line}", file=sys.stderr)
    return not stop, len(failures)


def last_line(path):
    try:
        with open(path, errors="replace") as f:
            lines = [l.strip() for l in f if l.strip()]
        return lines[-1] if lines else "no output"
    except OSError:
        return "no log"
