"""Facts about the binaries: where they are and what they say of themselves.

The scenarios, reward kinds and the credit modes each serves, permutations,
algorithms, every training default (per scenario, algorithm and reward kind),
the metrics.csv columns, caps and exit codes are defined once, in C++; the
tools ask (`<binary> --list`, `<binary> --print_config`) instead of copying
them. Nothing here decides anything of its own.
"""
import functools
import json
import os
import subprocess
import sys

# The clone: $IMCA_ROOT (./imca and ctest set it), else the folder above tools/.
ROOT = os.environ.get("IMCA_ROOT", os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
# The binaries: $IMCA_BIN (build-asan/bin under ./imca test --sanitize), else build/bin.
BIN = os.environ.get("IMCA_BIN", os.path.join(ROOT, "build", "bin"))


def load_time_env():
    """{name: value} of the binaries' load-time variables (BIN/load_time_env,
    which the build writes: OMP_WAIT_POLICY); {} before a build."""
    try:
        with open(os.path.join(BIN, "load_time_env")) as f:
            entries = f.read().split()
    except OSError:
        return {}
    return {name: value for name, sep, value in (e.partition("=") for e in entries) if sep and name}


# This process's environment gets them where unset, so that every binary a
# tool starts has them from its start: one started without re-executes
# itself to set them, loading LibTorch twice (common/base/load_time_env.h).
for _name, _value in load_time_env().items():
    os.environ.setdefault(_name, _value)

# The three services of a run, in start order.
PROGRAMS = ("reward_server", "learner", "actor")
# tools/, the folder this package is importable from (PYTHONPATH for a child
# that runs one of its modules).
TOOLS = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# The certificate maker ./imca train --secure, the tests and deploy/ use.
MAKE_CERTS = os.path.join(ROOT, "tools", "make_certs.sh")


class LaunchError(Exception):
    """A one-line, user-facing error."""


class Refused(LaunchError):
    """A binary refused its flags (`--print_config` failed); the message is its last line."""


def path(program):
    return os.path.join(BIN, program)


def module_argv(module, *args):
    """argv that runs this package's `module` (a CLI) in a child Python."""
    return [sys.executable, "-m", f"{__package__}.{module}", *args]


def module_env(env=None):
    """`env` (default: this process's) with this package importable: a child
    started with module_argv finds it whatever its working directory."""
    env = dict(os.environ if env is None else env)
    paths = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    if TOOLS not in paths:
        env["PYTHONPATH"] = os.pathsep.join([TOOLS] + paths)
    return env


@functools.lru_cache(maxsize=None)
def facts():
    """What the binaries say of themselves (`<binary> --list`): scenarios,
    reward kinds and the credit modes each serves, permutations, algorithms,
    the metrics.csv columns, caps and exit codes. One dict, the three
    programs' merged."""
    merged = {}
    for program in PROGRAMS:
        try:
            out = subprocess.run([path(program), "--list"], capture_output=True, text=True,
                                 errors="backslashreplace", timeout=120)
        except (OSError, subprocess.SubprocessError) as e:
            raise LaunchError(f"cannot run {path(program)} --list ({e}); build first: ./imca build") from e
        if out.returncode != 0:
            raise LaunchError(f"{path(program)} --list failed (exit {out.returncode}): {out.stderr.strip()}")
        for key, value in json.loads(out.stdout).items():
            if key != "program":
                merged[key] = value
    return merged


def per_agent_reward(reward):
    """True for the reward kinds whose per-agent bonus is the method itself
    (EITI, EDTI; docs/baselines.md): they serve no shared or imca credit, and run
    with credit independent (or none) and beta 1, their own coefficients
    (--eta, --beta-t) setting the scale."""
    return "imca" not in facts()["rewards"][reward]


def exit_refused():
    """The exit code of a client whose credentials a server refused
    (kExitRefused): restarting it would be refused again."""
    return facts()["exit_refused"]


def exit_misconfigured():
    """The exit code of a process whose configuration cannot work with its
    peers (kExitMisconfigured): a restart cannot either."""
    return facts()["exit_misconfigured"]


def print_config(program, flags):
    """`program --print_config` with `flags`: the configuration it resolves,
    validated by the binary itself (the one place that checks values).
    Refused (its last stderr line) if it refuses them."""
    out = subprocess.run([path(program), *flags, "--print_config"], capture_output=True, text=True,
                         errors="backslashreplace", timeout=120)
    if out.returncode != 0:
        raise Refused((out.stderr.strip().splitlines() or [f"exit {out.returncode}"])[-1])
    return json.loads(out.stdout)
