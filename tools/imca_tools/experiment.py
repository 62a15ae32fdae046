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
import contextlib
import fcntl
import functools
import hashlib
import io
import itertools
import json
import os
import shutil
import signal
import subprocess
import sys
import time

from . import binaries, options, plan, runs
from .binaries import ROOT

# Keys of a grid entry that may hold a list (expanded as a product) and the
# ./imca train flag each becomes. Anything else under "flags" is passed as is.
AXES = {"scenario": "--scenario", "reward": "--reward", "credit": "--credit", "permutation": "--permutation",
        "seed": "--seed", "steps": "--steps"}
# ./imca train flags that a grid's "flags" may not set: the axes, and what
# the runner itself controls.
RESERVED_FLAGS = set(AXES) | {"out", "resume", "quiet", "reward-port", "learner-port"}


def baselines():
    """The paper's baseline credit modes: every mode but imca."""
    return [c for c in binaries.facts()["credits"] if c != "imca"]


def pairing(scenario, reward, steps, seeds, maddpg=False):
    """The paper's methods on one scenario: three baselines, imca x permutations
    (and with `maddpg` the paper's other learner, MADDPG, without and with the
    IMCA bonus). SF's joint input is not permuted (docs/credit.md: permutations apply
    to count and RND), so its imca runs only with permutation off."""
    entries = [{"scenario": scenario, "reward": reward, "credit": baselines(), "permutation": "off",
                "seed": seeds, "steps": steps},
               {"scenario": scenario, "reward": reward, "credit": "imca",
                "permutation": "off" if reward == "sf" else binaries.facts()["permutations"], "seed": seeds, "steps": steps}]
    if maddpg:
        entries.append(maddpg_rows(scenario, reward, steps, seeds))
    return entries


def maddpg_rows(scenario, reward, steps, seeds):
    """MADDPG (docs/learner.md) with credit none and with the IMCA bonus."""
    return {"scenario": scenario, "reward": reward, "credit": ["none", "imca"], "permutation": "off",
            "seed": seeds, "steps": steps, "flags": {"algo": "maddpg"}}


# The task versions of CMAE's code and EDTI's (docs/scenarios.md).
CMAE_TASKS = ["pass_cmae", "secret_room_cmae", "push_box_cmae"]
EDTI_TASKS = ["pass", "secret_room"]
# The frontier preset's methods, one seed's worth of entries.
FRONTIER_METHODS = [
    {"scenario": CMAE_TASKS + EDTI_TASKS, "reward": "count", "credit": "none", "permutation": "off",
     "steps": 4_500_000, "flags": {"algo": "cmae"}},
    {"scenario": CMAE_TASKS, "reward": "count", "credit": ["none", "shared", "imca"], "permutation": "off",
     "steps": 4_500_000},
    {"scenario": CMAE_TASKS, "reward": "edti", "credit": "independent", "permutation": "off", "steps": 4_500_000},
    {"scenario": EDTI_TASKS, "reward": "count", "credit": ["none", "shared", "imca"], "permutation": "off",
     "steps": 3_000_000},
    {"scenario": EDTI_TASKS, "reward": "edti", "credit": "independent", "permutation": "off", "steps": 3_000_000},
]

# The multi_room3 preset's methods, one seed's worth of entries: 3 agents,
# where joint-state counts rarely repeat and learned novelty may generalise.
MULTI_ROOM3_METHODS = [
    {"scenario": "multi_room3_mace", "reward": "count", "credit": "none", "permutation": "off",
     "steps": 4_500_000},
    {"scenario": "multi_room3_mace", "reward": ["count", "rnd"], "credit": ["shared", "imca"], "permutation": "off",
     "steps": 4_500_000},
]


def seed_by_seed(methods, seeds):
    """Entries for each seed in turn, every method of one seed before the
    next (a grid cut short holds whole seeds of every method), each cell
    --deterministic."""
    return [dict(entry, seed=seed, flags={**entry.get("flags", {}), "deterministic": True})
            for seed in seeds for entry in methods]


@functools.lru_cache(maxsize=None)
def presets():
    """The built-in grids, by name (built when first asked: they use the
    binaries' lists of credit and permutation modes)."""
    return {
        "paper": {
            "description": "the paper's comparison: coop_nav + count, predator_prey + RND, multi_room + SF; "
                           "credit none/independent/shared/imca, imca with permutation off/random/canonical, "
                           "and MADDPG with credit none/imca; 5 seeds",
            "entries": pairing("coop_nav", "count", 2_000_000, [1, 2, 3, 4, 5], maddpg=True)
            + pairing("predator_prey", "rnd", 2_000_000, [1, 2, 3, 4, 5], maddpg=True)
            + pairing("multi_room", "sf", 4_000_000, [1, 2, 3, 4, 5], maddpg=True),
        },
        "edti": {
            "description": "EDTI's exact tasks pass and secret_room: count novelty with credit none/shared/imca "
                           "against EITI and EDTI (docs/baselines.md), and MADDPG with credit none/imca; 5 seeds; "
                           "3M env steps",
            "entries": [{"scenario": ["pass", "secret_room"], "reward": "count", "credit": ["none", "shared", "imca"],
                         "permutation": "off", "seed": [1, 2, 3, 4, 5], "steps": 3_000_000},
                        maddpg_rows(["pass", "secret_room"], "count", 3_000_000, [1, 2, 3, 4, 5]),
                        {"scenario": ["pass", "secret_room"], "reward": ["eiti", "edti"], "credit": "independent",
                         "permutation": "off", "seed": [1, 2, 3, 4, 5], "steps": 3_000_000}],
        },
        "headline": {
            "description": "the headline comparisons, 10 seeds, --deterministic: EDTI's pass and secret_room with "
                           "count novelty and credit none/shared/imca against EITI and EDTI (3M env steps), and "
                           "coop_nav with count novelty, credit shared and imca with permutation "
                           "off/random/canonical (2M)",
            "entries": [dict(entry, seed=list(range(1, 11)), flags={"deterministic": True}) for entry in [
                {"scenario": ["pass", "secret_room"], "reward": "count", "credit": ["none", "shared", "imca"],
                 "permutation": "off", "steps": 3_000_000},
                {"scenario": ["pass", "secret_room"], "reward": ["eiti", "edti"], "credit": "independent",
                 "permutation": "off", "steps": 3_000_000},
                {"scenario": "coop_nav", "reward": "count", "credit": "shared", "permutation": "off",
                 "steps": 2_000_000},
                {"scenario": "coop_nav", "reward": "count", "credit": "imca",
                 "permutation": binaries.facts()["permutations"], "steps": 2_000_000}]],
        },
        "frontier": {
            "description": "past the paper: CMAE (its released code's tabular method, docs/baselines.md) against "
                           "MAPPO with count novelty and credit none/shared/imca and against EDTI, on CMAE's "
                           "pass_cmae, secret_room_cmae and push_box_cmae (4.5M env steps: CMAE's 15,000 "
                           "episodes of 300; the bonuses at a thousandth, the scale of their +1 reward) and on "
                           "EDTI's pass and secret_room (CMAE 4.5M, the others 3M as in the headline preset); "
                           "10 seeds, --deterministic",
            "entries": seed_by_seed(FRONTIER_METHODS, range(1, 11)),
        },
        "multi_room3": {
            "description": "MACE's 3-agent MultiRoom (multi_room3_mace): count and RND novelty, each with credit "
                           "shared and imca, against MAPPO without a bonus; 4.5M env steps; 5 seeds, "
                           "--deterministic",
            "entries": seed_by_seed(MULTI_ROOM3_METHODS, range(1, 6)),
        },
        "quick": {
            "description": "a cut-down paper preset (2 seeds, smaller budgets) that ends in under 30 minutes on 2 cores",
            "entries": pairing("coop_nav", "count", 1_000_000, [1, 2])
            + pairing("predator_prey", "rnd", 400_000, [1, 2])
            + pairing("multi_room", "sf", 800_000, [1, 2]),
        },
    }


# Presets write to results/<preset>-<edition>: the learner's defaults changed
# with edition v2 (docs/benchmarks.md, "Sample efficiency against the
# reference MAPPO"), and results/<preset> holds the v1 runs (docs/results.md).
PRESET_EDITION = "v3"


class ExperimentError(Exception):
    """A one-line, user-facing error."""


# An axis a grid entry leaves out (permutation, seed, steps): ./imca train's default.
BINARY_DEFAULT = object()


def as_list(value):
    return value if isinstance(value, list) else [value]


def expand(entries, where):
    """Grid entries -> list of cells (dicts with every axis set, plus flags)."""
    cells = []
    for index, entry in enumerate(entries):
        name = f"{where}: entry {index}"
        if not isinstance(entry, dict):
            raise ExperimentError(f"{name}: must be an object")
        unknown = set(entry) - set(AXES) - {"flags"}
        if unknown:
            raise ExperimentError(f"{name}: unknown key '{sorted(unknown)[0]}' (keys: {', '.join(AXES)}, flags)")
        for key in ("scenario", "reward", "credit"):
            if key not in entry:
                raise ExperimentError(f"{name}: missing '{key}'")
        flags = entry.get("flags", {})
        if not isinstance(flags, dict):
            raise ExperimentError(f"{name}: 'flags' must be an object of ./imca train flags")
        flags = {key.replace("_", "-"): value for key, value in flags.items()}
        for key in flags:
            if key in RESERVED_FLAGS:
                raise ExperimentError(f"{name}: flag '{key}' is set by the grid itself"
                                      + (f" (use the entry's '{key}')" if key in AXES else ""))
        if len(flags) != len(entry.get("flags", {})):
            raise ExperimentError(f"{name}: 'flags' names a flag twice (dashes and underscores are the same)")
        # An axis the entry leaves out takes ./imca train's default (the binaries').
        values = {key: as_list(entry[key]) if key in entry else [BINARY_DEFAULT] for key in AXES}
        known = binaries.facts()
        for key, allowed in (("scenario", known["scenarios"]), ("reward", list(known["rewards"])),
                             ("credit", known["credits"]), ("permutation", known["permutations"])):
            for v in values[key]:
                if v is not BINARY_DEFAULT and v not in allowed:
                    raise ExperimentError(f"{name}: {key} '{v}' is not one of {', '.join(allowed)}")
        for key in ("seed", "steps"):
            for v in values[key]:
                if v is not BINARY_DEFAULT and (not isinstance(v, int) or isinstance(v, bool) or v < (0 if key == "seed" else 1)):
                    raise ExperimentError(f"{name}: {key} must be {'an integer >= 0' if key == 'seed' else 'a positive integer'}, got {v!r}")
        for combo in itertools.product(*(values[k] for k in AXES)):
            cell = dict(zip(AXES, combo), flags=dict(flags))
            cells.append(with_defaults(cell, known))
    unique = list({cell_id(cell): cell for cell in cells}.values())  # Grid order, each cell once.
    if not unique:
        raise ExperimentError(f"{where}: the grid has no cells")
    return unique


def with_defaults(cell, known):
    """`cell` with each axis it leaves out (BINARY_DEFAULT) set to the
    binaries' default for its scenario, reward kind and algorithm."""
    algo = cell["flags"].get("algo")
    # A wrong algo is check_flags' to name; the defaults are read for the default one meanwhile.
    algo = algo if algo in known["algos"] else known["default_algo"]
    args = argparse.Namespace(scenario=cell["scenario"], reward=cell["reward"], algo=algo)
    for key, flag in AXES.items():
        if cell[key] is BINARY_DEFAULT:
            cell[key] = options.default_of(flag, args)
    return cell


def flags_text(flags):
    return " ".join(f"{key}={value}" for key, value in sorted(flags.items()))


def labeller(cells):
    """method(cell) -> row label: credit, imca's permutation, and those extra
    flags that differ between cells of the same scenario and reward."""
    def settings(cell):
        return dict(cell["flags"], steps=cell["steps"])

    by_pair = {}
    for cell in cells:
        by_pair.setdefault((cell["scenario"], cell["reward"]), []).append(settings(cell))
    # Per scenario and reward: the settings whose value (or absence) differs.
    varying = {pair: {key for key in set().union(*group) if len({json.dumps(s.get(key)) for s in group}) > 1}
               for pair, group in by_pair.items()}

    def method(cell):
        # EITI and EDTI are methods of their own (their per-agent bonus is
        # the method), named by their reward kind.
        per_agent = binaries.per_agent_reward(cell["reward"]) and cell["credit"] == "independent"
        label = cell["reward"] if per_agent else cell["credit"]
        if cell["permutation"] != "off":
            label += f"/{cell['permutation']}"
        # Another learner algorithm than MAPPO leads the label ("maddpg imca");
        # CMAE's is its name alone (it uses no reward server bonus).
        algo = cell["flags"].get("algo", "mappo")
        if algo == "cmae":
            label = "cmae"
        elif algo != "mappo":
            label = f"{algo} {label}"
        shown = {k: v for k, v in settings(cell).items()
                 if k in varying[(cell["scenario"], cell["reward"])] and k != "algo"}
        return label + (" " + flags_text(shown) if shown else "")

    return method


def cell_id(cell):
    parts = [cell["scenario"], cell["reward"], cell["credit"], cell["permutation"], f"s{cell['seed']}",
             f"{cell['steps'] // 1000}k" if cell["steps"] % 1000 == 0 else str(cell["steps"])]
    if cell["flags"]:
        # Extra flags by a short digest; grid.json and config.json spell them out.
        parts.append("f" + hashlib.sha1(json.dumps(cell["flags"], sort_keys=True).encode()).hexdigest()[:8])
    return "-".join(parts)


def train_flags(cell, out):
    """The ./imca train flags of a cell's run in `out`."""
    argv = ["--out", out]
    for key, flag in AXES.items():
        argv += [flag, str(cell[key])]
    for key, value in sorted(cell["flags"].items()):
        argv += [f"--{key}", str(value)]
    return argv


def train_argv(cell, out):
    return binaries.module_argv("train", "--quiet", *train_flags(cell, out))


def check_flags(cells):
    """Every cell's flags must be ones ./imca train takes, with values the
    binaries accept (one-line error otherwise)."""
    checked = set()
    for cell in cells:
        key = json.dumps(cell["flags"], sort_keys=True)
        if key in checked:
            continue
        checked.add(key)
        argv = train_flags(cell, "unused")
        captured = io.StringIO()
        try:
            with contextlib.redirect_stderr(captured):
                # The binaries check the values (--print_config), as a start would.
                plan.plan(plan.parse_args(argv))
        except SystemExit:
            why = captured.getvalue().strip().removeprefix("imca train: ")
            raise ExperimentError(f"flags {json.dumps(cell['flags'])}: {why}")
        except binaries.LaunchError as error:
            raise ExperimentError(f"flags {json.dumps(cell['flags'])}: {error}")


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


def cell_dir(out, cell):
    return os.path.join(out, "cells", cell_id(cell))


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


def deterministic(cell):
    return bool(cell["flags"].get("deterministic"))


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

    from . import cluster  # The backends (cluster imports this module).

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
        from . import report  # matplotlib only once something is to be drawn

        results = {cell_id(c): finished(cell_dir(out, c), c) for c in cells}
        report.write(out, cells, results, labeller(cells), cell_id)
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


def only(cells, names):
    """The cells --only names (all without it); a name that is no cell is a one-line error."""
    if not names:
        return cells
    wanted = names.split(",")
    ids = {cell_id(c) for c in cells}
    for name in wanted:
        if name not in ids:
            raise ExperimentError(f"--only: '{name}' is not a cell of this grid (--status lists them)")
    return [c for c in cells if cell_id(c) in wanted]


def load_grid(path):
    try:
        with open(path) as f:
            grid = json.load(f)
    except OSError as e:
        raise ExperimentError(f"--grid: cannot read '{path}': {e.strerror}")
    except ValueError as e:
        raise ExperimentError(f"--grid: '{path}' is not valid JSON: {e}")
    if not isinstance(grid, dict) or not isinstance(grid.get("entries"), list):
        raise ExperimentError(f"--grid: '{path}' must be an object with a list 'entries'")
    grid.setdefault("name", os.path.splitext(os.path.basename(path))[0])
    if not isinstance(grid["name"], str) or not grid["name"] or "/" in grid["name"]:
        raise ExperimentError("--grid: 'name' must be a non-empty string without '/'")
    return grid


def save_grid(out, grid):
    path = os.path.join(out, "grid.json")
    if os.path.exists(path):
        try:
            with open(path) as f:
                saved = json.load(f)
        except (OSError, ValueError):
            saved = {}
        if saved.get("entries") != json.loads(json.dumps(grid["entries"])):
            print(f"imca experiment: note: {out} held another grid; its finished cells that are "
                  f"also in this one are kept", file=sys.stderr)
    with open(path + ".tmp", "w") as f:
        json.dump(grid, f, indent=2)
    os.replace(path + ".tmp", path)


def load_saved_grid(out, flag="--report"):
    path = os.path.join(out, "grid.json")
    if not os.path.isfile(path):
        raise ExperimentError(f"{flag}: '{out}' holds no experiment (grid.json)")
    return load_grid(path)


if __name__ == "__main__":
    # The package's module, not __main__: imca_tools.cluster raises this
    # module's ExperimentError, which main catches.
    from imca_tools import experiment
    sys.exit(experiment.main(sys.argv[1:]))
