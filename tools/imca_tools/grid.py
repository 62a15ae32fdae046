"""A grid of training runs: its entries, their expansion into cells (one
./imca train run each, named by cell_id), each cell's ./imca train flags
checked as ./imca train checks them (imca_tools.plan), and the grid's file
(grid.json) read and saved. Nothing here runs a cell (imca_tools.runner,
imca_tools.cluster) or draws one (imca_tools.report).
"""
import argparse
import contextlib
import hashlib
import io
import itertools
import json
import os
import sys

from . import binaries, options, plan


# Keys of a grid entry that may hold a list (expanded as a product) and the
# ./imca train flag each becomes. Anything else under "flags" is passed as is.
AXES = {"scenario": "--scenario", "reward": "--reward", "credit": "--credit", "permutation": "--permutation",
        "seed": "--seed", "steps": "--steps"}


# ./imca train flags that a grid's "flags" may not set: the axes, and what
# the runner itself controls.
RESERVED_FLAGS = set(AXES) | {"out", "resume", "quiet", "reward-port", "learner-port"}


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


def cell_dir(out, cell):
    return os.path.join(out, "cells", cell_id(cell))


def deterministic(cell):
    return bool(cell["flags"].get("deterministic"))


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
