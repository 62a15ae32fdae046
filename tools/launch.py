#!/usr/bin/python3
"""./imca train: one reward server, one learner and N actors on loopback.

Starts the three services as separate processes on free ports, shows a live
progress line, and leaves a run folder (docs/usage.md, "What a run leaves").
Ctrl-C stops every process in order (actors, learner, reward server) and still
leaves a valid run folder.
"""
import argparse
import csv
import datetime
import functools
import json
import os
import re
import signal
import subprocess
import sys
import time

ROOT = os.environ.get("IMCA_ROOT", os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("IMCA_BIN", os.path.join(ROOT, "build", "bin"))
PROGRAMS = ("reward_server", "learner", "actor")


class LaunchError(Exception):
    """A one-line, user-facing error."""


@functools.lru_cache(maxsize=None)
def facts():
    """What the binaries say of themselves (`<binary> --list`): scenarios,
    reward kinds and the credit modes each serves, permutations, algorithms,
    the metrics.csv columns, caps and exit codes. Defined once, in C++; the
    tools ask instead of copying them. One dict, the three programs' merged."""
    merged = {}
    for program in PROGRAMS:
        path = os.path.join(BIN, program)
        try:
            out = subprocess.run([path, "--list"], capture_output=True, text=True, timeout=120)
        except (OSError, subprocess.SubprocessError) as e:
            raise LaunchError(f"cannot run {path} --list ({e}); build first: ./imca build") from e
        if out.returncode != 0:
            raise LaunchError(f"{path} --list failed (exit {out.returncode}): {out.stderr.strip()}")
        for key, value in json.loads(out.stdout).items():
            if key != "program":
                merged[key] = value
    return merged


def per_agent_reward(reward):
    """True for the reward kinds whose per-agent bonus is the method itself
    (EITI, EDTI; BASELINES.md 1): they serve no shared or imca credit, and run
    with credit independent (or none) and beta 1, their own coefficients
    (--eta, --beta-t) setting the scale."""
    return "imca" not in facts()["rewards"][reward]


def exit_refused():
    """The exit code of a client whose credentials a server refused
    (kExitRefused): restarting it would be refused again."""
    return facts()["exit_refused"]


def positive_int(text):
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {text}")
    return value


def boolean(text):
    value = str(text).lower()
    if value in ("1", "true", "on", "yes"):
        return True
    if value in ("0", "false", "off", "no"):
        return False
    raise argparse.ArgumentTypeError(f"must be true or false, got {text}")


# The ./imca train flags that set a binary's flag: (flag, {program: the
# binary's flag}, argparse keywords). Each is passed on only when given (or
# recorded by a run being resumed), so that the binaries' defaults, in C++
# beside what they configure (and the scenario's and reward kind's
# differences beside their specs), are the one definition: `<binary>
# --list` prints them per scenario, and parse_args fills what was not given
# from there, for the record and the progress line. docs/learner.md.
SCENARIO = ("reward_server", "learner", "actor", "imca_env")  # The env tool renders the episode GIF.
OPTIONS = [
    ("--scenario", {p: "scenario" for p in SCENARIO}, dict(choices=lambda k: k["scenarios"])),
    ("--num-agents", {p: "num_agents" for p in SCENARIO}, dict(type=int, help="agents (default: the scenario's)")),
    ("--step-limit", {p: "step_limit" for p in SCENARIO}, dict(type=int, help="episode step limit (default: the scenario's)")),
    ("--view-radius", {p: "view_radius" for p in SCENARIO}, dict(type=int, help="partial observation radius (0: full)")),
    ("--door-timer", {p: "door_timer" for p in SCENARIO},
     dict(type=int, help="door scenarios: EDTI's door-open interval doi (default: the scenario's; docs/scenarios.md)")),
    ("--reward", {"reward_server": "reward"}, dict(choices=lambda k: list(k["rewards"]), help="global novelty kind")),
    ("--credit", {"reward_server": "credit"}, dict(choices=lambda k: k["credits"],
                                                   help="credit mode (default: imca; independent for eiti and edti)")),
    ("--permutation", {"reward_server": "permutation"}, dict(choices=lambda k: k["permutations"])),
    ("--beta", {"reward_server": "beta"}, dict(type=float, help="coefficient of the global bonus (default 0.5; 1 for eiti, edti)")),
    ("--eta", {"reward_server": "eta"}, dict(type=float, help="eiti, edti: coefficient of the decentralised curiosity")),
    ("--beta-t", {"reward_server": "beta_t"}, dict(type=float, help="eiti: coefficient of the summed influence")),
    ("--temperature", {"reward_server": "temperature"}, dict(type=float, help="softmax temperature of the shares")),
    ("--snapshot-every", {"reward_server": "snapshot_every"},
     dict(type=int, help="reward server snapshot interval in s (count kinds also journal every increment)")),
    ("--seed", {"reward_server": "seed", "learner": "seed"},
     dict(type=int, help="seed of the run (actor i acts with seed * 1000 + i + 1)")),
    ("--algo", {"learner": "algo"}, dict(choices=lambda k: k["algos"],
                                         help="mappo (on-policy PPO) or maddpg (off-policy; docs/learner.md)")),
    ("--steps", {"learner": "steps"}, dict(type=positive_int, help="budget in joint env steps")),
    ("--actors", {"learner": "actors"}, dict(type=positive_int, help="actor processes")),
    ("--batch-steps", {"learner": "batch_steps"}, dict(type=positive_int,
                                                       help="joint env steps per PPO iteration (default: the scenario's)")),
    ("--max-batch-mb", {"learner": "max_batch_mb"},
     dict(type=positive_int, help="learner's cap on an iteration's feature memory (docs/learner.md)")),
    ("--lr", {"learner": "lr"}, dict(type=float, help="Adam learning rate (default: the scenario's)")),
    ("--entropy-coef", {"learner": "entropy_coef"}, dict(type=float, help="entropy bonus coefficient")),
    ("--intrinsic-coef", {"learner": "intrinsic_coef"}, dict(type=float, help="weight of the intrinsic advantage")),
    ("--separate-optimizers", {"learner": "separate_optimizers"},
     dict(type=boolean, metavar="BOOL",
          help="one Adam and grad clip each for actor and critic, false: one over both (default: the scenario's)")),
    ("--sync", {"learner": "synchronous"},
     dict(type=boolean, metavar="BOOL",
          help="synchronous collection: every iteration trains on the policy it starts from, each actor acting "
               "batch steps / actors of it (default: true for mappo, false for maddpg)")),
    ("--checkpoint-seconds", {"learner": "checkpoint_seconds"},
     dict(type=float, help="learner checkpoint interval: what a learner restart loses at most")),
    ("--objective", {"learner": "objective"}, dict(choices=lambda k: k["objectives"],
                                                   help="PPO clip against the behaviour policy or a recomputed proximal one")),
    ("--layer-norm", {"learner": "layer_norm"}, dict(type=boolean, metavar="BOOL",
                                                     help="LayerNorm on input and hidden layers")),
    ("--value-heads", {"learner": "value_heads"}, dict(type=int, choices=[1, 2], help="2: extrinsic + intrinsic heads; 1: one")),
    ("--critic-input", {"learner": "critic_input"}, dict(choices=lambda k: k["critic_inputs"], help="centralised critic's input")),
    ("--time-limit", {"learner": "time_limit"}, dict(choices=lambda k: k["time_limits"], help="the step limit in the returns")),
    ("--hidden-gain", {"learner": "hidden_gain"}, dict(type=float, help="orthogonal init gain of hidden layers")),
    ("--value-clip", {"learner": "value_clip"}, dict(type=float, help="value clipping range (0: off)")),
    ("--huber-delta", {"learner": "huber_delta"}, dict(type=float, help="Huber value loss delta (0: MSE)")),
    ("--value-coef", {"learner": "value_coef"}, dict(type=float, help="value loss weight")),
    ("--max-grad-norm", {"learner": "max_grad_norm"}, dict(type=float, help="gradient-norm clip")),
    ("--epochs", {"learner": "epochs"}, dict(type=positive_int, help="PPO epochs per iteration")),
    ("--minibatches", {"learner": "minibatches"}, dict(type=positive_int, help="PPO minibatches per epoch")),
    ("--max-policy-lag", {"learner": "max_policy_lag"},
     dict(type=int, help="mappo: drop unrolls older than this many versions")),
    ("--learner-threads", {"learner": "threads"}, dict(type=positive_int,
                                                       help="LibTorch threads of each learner pass")),
    ("--gamma", {"learner": "gamma"}, dict(type=float, help="extrinsic discount (MADDPG: its only one)")),
    ("--updates-per-step", {"learner": "updates_per_step"},
     dict(type=float, help="maddpg: gradient steps per joint env step; actors are slowed to it")),
    ("--maddpg-share", {"learner": "maddpg_share"}, dict(type=boolean, metavar="BOOL",
                                                         help="maddpg: one actor and critic for all agents (agent id input)")),
    ("--maddpg-batch", {"learner": "maddpg_batch"}, dict(type=positive_int,
                                                         help="maddpg: transitions per gradient step")),
    ("--maddpg-buffer", {"learner": "maddpg_buffer"}, dict(type=positive_int, help="maddpg: replay capacity")),
    ("--maddpg-learning-starts", {"learner": "maddpg_learning_starts"},
     dict(type=positive_int, help="maddpg: replay transitions before the first update")),
    ("--maddpg-actor-lr", {"learner": "maddpg_actor_lr"}, dict(type=float, help="maddpg: the actors' Adam learning rate")),
    ("--maddpg-critic-lr", {"learner": "maddpg_critic_lr"}, dict(type=float, help="maddpg: the critics' Adam learning rate")),
    ("--maddpg-tau", {"learner": "maddpg_tau"}, dict(type=float, help="maddpg: soft target update rate")),
    ("--concurrent-critic", {"learner": "concurrent_critic"}, dict(type=boolean, metavar="BOOL",
                                                                   help="critic passes on a second learner thread")),
    ("--envs-per-actor", {"actor": "envs"}, dict(type=positive_int, help="environments of each actor")),
    ("--unroll-length", {"actor": "unroll_length"}, dict(type=positive_int,
                                                         help="steps per unroll (default: the scenario's)")),
]


def dest(flag):
    return flag[2:].replace("-", "_")


# ./imca train's defaults before the learner ablation (docs/benchmarks.md,
# "Sample efficiency against the reference MAPPO"); a run folder that did not
# record one of these settings ran with it.
V1_DEFAULTS = {"sync": False, "batch_steps": 8192, "unroll_length": 64, "separate_optimizers": False, "lr": 5e-4}


def resolved_defaults(args):
    """{program: {binary flag: default}} for the scenario, algorithm and
    reward kind of args: what `<program> --list` resolves."""
    known = facts()
    return {"reward_server": known["reward_defaults"][args.reward],
            "learner": known["learner_defaults"][args.algo][args.scenario],
            "actor": known["actor_defaults"][args.scenario]}


class OneLineParser(argparse.ArgumentParser):
    """Flag errors as one line naming the flag (no usage dump)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: {message}\n")


def dashed(argv):
    """argv with every flag name spelled with hyphens: ./imca takes
    --door_timer as --door-timer (the binaries' own spelling) everywhere and
    documents the hyphens. Values and what follows a bare "--" are untouched."""
    out = list(argv)
    for i, word in enumerate(out):
        if word == "--":
            break
        if word.startswith("--"):
            name, eq, value = word.partition("=")
            out[i] = "--" + name[2:].replace("_", "-") + eq + value
    return out


def parse_args(argv):
    argv = dashed(argv)
    p = OneLineParser(prog="imca train", description=__doc__,
                      formatter_class=argparse.RawDescriptionHelpFormatter)
    known = facts()
    for flag, _, keywords in OPTIONS:
        keywords = dict(keywords)
        if callable(keywords.get("choices")):
            keywords["choices"] = keywords["choices"](known)
        p.add_argument(flag, default=None, **keywords)
    p.add_argument("--map", default="", help="map file (default: maps/<scenario>.txt)")
    p.add_argument("--out", default="", help="run folder (default: runs/<timestamp>)")
    p.add_argument("--reward-port", type=int, default=0, help="reward server port (0: a free one)")
    p.add_argument("--learner-port", type=int, default=0, help="learner port (0: a free one)")
    p.add_argument("--metrics-port", type=int, default=0, metavar="N",
                   help="serve Prometheus metrics on 127.0.0.1: the reward server on N, the learner on N+1, "
                        "actor i on N+2+i; writes <run>/prometheus.yml to scrape them (0: no endpoints; "
                        "docs/metrics.md)")
    p.add_argument("--resume", default="", metavar="RUN_DIR",
                   help="continue a stopped run in RUN_DIR with its saved config; --steps is the total budget")
    p.add_argument("--max-restarts", type=int, default=5,
                   help="restarts of each process before the run gives up (0: none; docs/reliability.md)")
    p.add_argument("--stall-seconds", type=float, default=60.0,
                   help="a process with no progress for this long is restarted")
    p.add_argument("--secure", action="store_true",
                   help="mutual TLS and a bearer token on every connection: a throwaway CA, certificates and "
                        "token are made in <run folder>/tls with openssl (docs/security.md)")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    args = p.parse_args(argv)
    # What the user gave (or the resumed run recorded): the flags passed on.
    args.given = sorted(dest(flag) for flag, _, _ in OPTIONS if getattr(args, dest(flag)) is not None)
    if args.resume:
        config_path = os.path.join(args.resume, "config.json")
        if not os.path.isfile(config_path) or not os.path.isdir(os.path.join(args.resume, "checkpoints")):
            p.error(f"argument --resume: '{args.resume}' holds no run (config.json and checkpoints/)")
        with open(config_path) as f:
            saved = json.load(f)
        # A run from before the defaults changed did not record the setting
        # (or recorded None: the binary's default then); it resumes as it ran.
        for key, old in V1_DEFAULTS.items():
            if saved.get(key) is None:
                saved[key] = old
        saved.setdefault("algo", "mappo")  # Runs from before --algo trained MAPPO.
        given = set(args.given)
        for key, value in saved.items():
            if key in ("steps", "out", "resume", "reward_port", "learner_port", "given", "resolved"):
                continue
            if hasattr(args, key) and value is not None:
                setattr(args, key, value)
                given.add(key)
        # Every recorded setting is passed on: the run resumes as it ran,
        # whatever the defaults are now.
        args.given = sorted(k for k in given if k in {dest(f) for f, _, _ in OPTIONS})
        args.out = args.resume
    # The three choices the other defaults depend on, first.
    for choice in ("scenario", "algo", "reward"):
        if getattr(args, choice) is None:
            setattr(args, choice, known[f"default_{choice}"])
    defaults = resolved_defaults(args)
    for flag, programs, _ in OPTIONS:
        if getattr(args, dest(flag)) is None:
            program, name = next(iter(programs.items()))
            setattr(args, dest(flag), defaults[program].get(name))
    if args.metrics_port and not 1 <= args.metrics_port <= 65535 - 1 - args.actors:
        p.error(f"argument --metrics-port: must be in [1, {65535 - 1 - args.actors}] "
                f"(it takes N .. N+{1 + args.actors}), or 0 for no endpoints")
    if args.max_restarts < 0:
        p.error("argument --max-restarts: must be >= 0")
    if args.stall_seconds < 10:
        # An actor waiting for a policy refreshes its status once per long
        # poll (up to 5 s); a shorter limit would restart healthy waiters.
        p.error("argument --stall-seconds: must be >= 10")
    if args.map and not os.path.isfile(args.map):
        p.error(f"argument --map: no such file '{args.map}'")
    return args


def program_flags(args, program):
    """The training flags ./imca train passes to `program`: those of the
    options given (the rest are the binary's defaults), in OPTIONS order."""
    flags = []
    for flag, programs, _ in OPTIONS:
        name = programs.get(program)
        if name is None or dest(flag) not in args.given:
            continue
        value = getattr(args, dest(flag))
        flags.append(f"--{name}={str(value).lower() if isinstance(value, bool) else value}")
    if program == "learner" and args.reward == "edti":
        flags.append("--edti=true")  # EDTI's value of interaction: the learner's half of --reward edti.
    return flags


def print_config(args, program, flags):
    """`program --print_config` with `flags`: the configuration it resolves,
    validated by the binary itself (the one place that checks values). A
    refusal is a LaunchError naming the ./imca train flag."""
    path = os.path.join(BIN, program)
    out = subprocess.run([path, *flags, "--print_config"], capture_output=True, text=True, timeout=120)
    if out.returncode != 0:
        message = (out.stderr.strip().splitlines() or [f"exit {out.returncode}"])[-1]
        # The given option the message names first (past its "program: --flag value:" context).
        reason = re.sub(r"^\w+: (--\w+ \S+: )?", "", message)
        named = []
        for flag, programs, _ in OPTIONS:
            name = programs.get(program)
            found = re.search(rf"(?<!\w){re.escape(name)}(?!\w)", reason) if name else None
            if found and dest(flag) in args.given:
                named.append((found.start(), flag))
        raise LaunchError(f"argument {min(named)[1]}: {message}" if named else message)
    return json.loads(out.stdout)


def _die_with_parent():
    """In the child before exec: SIGTERM when the launcher dies, even by kill -9
    (so that no child outlives it), and a new session, so that the terminal's
    Ctrl-C reaches only the launcher, which then stops the children in order."""
    os.setsid()
    try:
        import ctypes
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except OSError:
        pass


def read_json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


class Services:
    """The child processes of one run, supervised and stopped in dependency order.

    A child that dies (any exit but a finished one) is started again with the
    same argv plus `restart_args`, after a backoff of 1 s doubling to 30 s;
    past `max_restarts` restarts of one process the run ends with one line
    naming it and its last log line. A child whose status file (written every
    second by each binary) goes quiet for `stall_seconds`, or whose own
    status says it is stalled, is killed and restarted the same way. Each
    incarnation logs to logs/<name>.log, logs/<name>.1.log, ...; every restart
    is a row of logs/restarts.csv.
    """

    def __init__(self, run_dir, max_restarts=5, stall_seconds=60.0):
        self.run_dir = run_dir
        self.logs = os.path.join(run_dir, "logs")
        os.makedirs(self.logs, exist_ok=True)
        self.max_restarts = max_restarts
        self.stall_seconds = stall_seconds
        self.procs = []  # [name, Popen], in start order.
        self.argv = {}
        self.restart_args = {}
        self.restarts = {}
        self.started = {}
        self.pending = {}  # name -> time at which to start it again.
        self.log_names = {}
        self.finished_codes = {}
        self._learner_steps, self._learner_moved = None, time.time()  # check_deadlock's.

    def status_file(self, name):
        return os.path.join(self.logs, name + ".status.json")

    def log_path(self, name):
        return os.path.join(self.logs, self.log_names.get(name, name + ".log"))

    def start(self, name, argv, restart_args=None, finished_codes=(0,)):
        self.argv[name] = list(argv)
        self.restart_args[name] = restart_args or (lambda: [])
        self.restarts.setdefault(name, 0)
        self.finished_codes[name] = finished_codes
        return self._spawn(name, list(argv) + [f"--status_file={self.status_file(name)}"])

    def _spawn(self, name, argv):
        k = self.restarts[name]
        self.log_names[name] = f"{name}.log" if k == 0 else f"{name}.{k}.log"
        try:
            os.remove(self.status_file(name))
        except OSError:
            pass
        log = open(self.log_path(name), "ab")
        proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, preexec_fn=_die_with_parent,
                                env=dict(os.environ, OMP_WAIT_POLICY="passive"))
        log.close()
        for entry in self.procs:
            if entry[0] == name:
                entry[1] = proc
                break
        else:
            self.procs.append([name, proc])
        self.started[name] = time.time()
        return proc

    def proc(self, name):
        return next(p for n, p in self.procs if n == name)

    def last_log_line(self, name):
        try:
            with open(self.log_path(name), errors="replace") as f:
                lines = [l.strip() for l in f if l.strip()]
            return lines[-1] if lines else f"{name} exited"
        except OSError:
            return f"{name} exited"

    def wait_port(self, name, proc, port_file, timeout=30.0):
        deadline = time.time() + timeout
        while time.time() < deadline:
            if proc.poll() is not None:
                raise LaunchError(self.last_log_line(name))
            try:
                with open(port_file) as f:
                    text = f.read().strip()
                if text:
                    return int(text)
            except OSError:
                pass
            time.sleep(0.05)
        raise LaunchError(f"{name} did not start serving within {timeout:.0f} s")

    def _stalled(self, name, now):
        """Why `name` counts as stalled, or None."""
        status = read_json(self.status_file(name))
        if status is None or "time" not in status:
            # Starting up (a reward server replaying a long journal, a learner
            # loading a checkpoint) gets a longer grace before its first status.
            if now - self.started[name] > 2 * self.stall_seconds + 60:
                return f"no status {now - self.started[name]:.0f} s after its start"
            return None
        quiet = now - max(status["time"], self.started[name])
        if quiet > self.stall_seconds:
            return f"no status for {quiet:.0f} s"
        if status.get("seconds_stalled", 0) > self.stall_seconds:
            return f"unrolls waited {status['seconds_stalled']:.0f} s without training"
        if status.get("seconds_training", 0) > 10 * self.stall_seconds:
            return f"one PPO update has run for {status['seconds_training']:.0f} s"
        return None

    def _record(self, name, reason):
        path = os.path.join(self.logs, "restarts.csv")
        fresh = not os.path.exists(path)
        with open(path, "a") as f:
            if fresh:
                f.write("time,process,restart,reason\n")
            f.write(f"{time.time():.3f},{name},{self.restarts[name]},\"{reason}\"\n")

    def supervise(self, names):
        """Restarts what died or stalled among `names`; raises past the cap.
        Returns the names that finished (exited with a finished code)."""
        now = time.time()
        finished = []
        for name in names:
            if name in self.pending:
                if now >= self.pending[name]:
                    del self.pending[name]
                    self._spawn(name, self.argv[name] + self.restart_args[name]()
                                + [f"--status_file={self.status_file(name)}"])
                continue
            proc = self.proc(name)
            code = proc.poll()
            if code is not None and code in self.finished_codes[name]:
                finished.append(name)
                continue
            if code == exit_refused():
                # A server refused its credentials: the same ones would be
                # refused again, so no restart.
                raise LaunchError(f"{name} was refused by a server (exit {code}): {self.last_log_line(name)}")
            if code == facts()["exit_misconfigured"]:
                # Its configuration cannot work with its peers: neither can a restart's.
                raise LaunchError(f"{name} cannot work with its peers (exit {code}): {self.last_log_line(name)}")
            reason = None
            if code is not None:
                reason = f"exited with code {code}"
            else:
                stalled = self._stalled(name, now)
                if stalled:
                    reason = f"made no progress ({stalled})"
                    proc.kill()
                    proc.wait()
            if reason is None:
                continue
            last = self.last_log_line(name)
            if self.restarts[name] >= self.max_restarts:
                raise LaunchError(f"{name} {reason}, {self.restarts[name]} restarts already (--max-restarts): {last}")
            delay = min(30.0, 2.0 ** self.restarts[name])
            self.restarts[name] += 1
            self._record(name, f"{reason}: {last}".replace('"', "'"))
            print(f"\nimca train: {name} {reason} ({last}); restart {self.restarts[name]} in {delay:.0f} s",
                  file=sys.stderr, flush=True)
            self.pending[name] = now + delay
        return finished

    def check_deadlock(self, learner, actors):
        """A net under protocol bugs: the learner has not trained for twice
        stall_seconds while every actor waits for a policy (each side waits
        for the other). Kills the actors, which supervise() then restarts:
        a fresh actor acts with whatever policy the learner has."""
        now = time.time()
        status = read_json(self.status_file(learner)) or {}
        steps = status.get("env_steps")
        if steps != self._learner_steps or learner in self.pending or status.get("seconds_training", 0) > 0:
            self._learner_steps, self._learner_moved = steps, now
            return
        # Twice the stall limit, and only with every actor alive and saying
        # so: a silent actor is the stall detector's to restart, first.
        if now - self._learner_moved < 2 * self.stall_seconds or any(a in self.pending for a in actors):
            return
        statuses = [read_json(self.status_file(a)) or {} for a in actors]
        if statuses and all(st.get("state") == "waiting_policy" and now - st.get("time", 0) < self.stall_seconds / 2
                            for st in statuses):
            print(f"\nimca train: the learner has not trained for {now - self._learner_moved:.0f} s while every "
                  "actor waits for a policy; restarting the actors", file=sys.stderr, flush=True)
            for a in actors:
                self.proc(a).kill()
            self._learner_moved = now

    def total_restarts(self):
        return sum(self.restarts.values())

    def stop(self, names=None, timeout=30.0):
        """SIGTERM to all of `names` at once, then wait; returns {name: exit code}."""
        codes = {}
        for name in list(self.pending):
            if names is None or name in names:
                del self.pending[name]  # Never started again.
        chosen = [(n, p) for n, p in self.procs if names is None or n in names]
        for name, proc in chosen:
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        for name, proc in chosen:
            try:
                codes[name] = proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                codes[name] = proc.wait()
        return codes


def read_metrics(path):
    try:
        with open(path) as f:
            return list(csv.DictReader(f))
    except OSError:
        return []


def fmt_duration(seconds):
    seconds = int(max(seconds, 0))
    if seconds >= 3600:
        return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m"
    return f"{seconds // 60}m{seconds % 60:02d}s"


def progress_line(row, budget, restarts=0):
    steps = int(row["env_steps"])
    rate = float(row["env_steps_per_sec"])
    eta = (budget - steps) / rate if rate > 0 else 0
    return (f"steps {steps:,}/{budget:,} | {rate:,.0f} steps/s | success {float(row['success_rate']):.1%}"
            f" | return {float(row['episode_return']):.2f} | intrinsic {float(row['intrinsic_reward']):.4f}"
            f" | ETA {fmt_duration(eta)}" + (f" | restarts {restarts}" if restarts else ""))


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
        if window in row and int(row[window]) < facts()["success_window"]:
            continue
        if float(row[key]) >= threshold:
            return row
    return None


def steps_to(rows, threshold, key="success_rate"):
    row = first_reaching(rows, threshold, key)
    return int(row["env_steps"]) if row else None


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
    }
    write_json_atomically(os.path.join(run_dir, "summary.json"), summary)
    return summary


def write_json_atomically(path, value):
    """A file a crash leaves old or new, never half (as common/atomic_file.h)."""
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


def plot(run_dir, rows, title):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    steps = [int(r["env_steps"]) for r in rows]
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    series = [("success_rate", "evaluation success rate"), ("episode_return", "episode return (team)"),
              ("intrinsic_reward", "mean intrinsic reward / agent-step")]
    for ax, (key, label) in zip(axes, series):
        ax.plot(steps, [float(r[key]) for r in rows], lw=1.5)
        ax.set_xlabel("env steps")
        ax.set_title(label, fontsize=10)
        ax.grid(alpha=0.3)
    axes[0].set_ylim(-0.02, 1.02)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    fig.savefig(os.path.join(run_dir, "learning_curve.png"), dpi=110)
    plt.close(fig)


def episode_gif(run_dir, scenario_flags, seed):
    """One episode of the final policy as episode.gif (best effort: a run
    stopped before its first checkpoint has no policy.pb)."""
    policy = os.path.join(run_dir, "policy.pb")
    if not os.path.exists(policy):
        return
    r = subprocess.run([os.path.join(BIN, "imca_env"), "rollout", *scenario_flags, f"--policy={policy}",
                        f"--seed={seed}", "--json", f"--gif={os.path.join(run_dir, 'episode.gif')}"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        print(f"imca train: no episode.gif: {r.stderr.strip()}", file=sys.stderr)


def secure_flags(run_dir, args):
    """Makes (or, on resume, reuses) the run's CA, certificates and token in
    <run_dir>/tls; returns the servers' flags and a function of the actor
    index giving its flags (its own client certificate, CN=actor-<i>)."""
    tls = os.path.join(run_dir, "tls")
    clients = [f"actor-{i}" for i in range(args.actors)]
    if not all(os.path.exists(os.path.join(tls, f"{c}.pem")) for c in clients + ["ca", "server"]):
        r = subprocess.run([os.path.join(ROOT, "tools", "make_certs.sh"), tls] + clients,
                           capture_output=True, text=True)
        if r.returncode != 0:
            raise LaunchError(f"--secure: making certificates with openssl failed: {r.stderr.strip()}")
    path = lambda name: os.path.join(tls, name)
    server = [f"--tls_cert={path('server.pem')}", f"--tls_key={path('server.key')}", f"--tls_ca={path('ca.pem')}",
              "--tls_client_auth=true", f"--token_file={path('token')}"]
    actor = lambda i: [f"--tls_ca={path('ca.pem')}", f"--tls_cert={path(f'actor-{i}.pem')}",
                       f"--tls_key={path(f'actor-{i}.key')}", f"--token_file={path('token')}"]
    return server, actor


def metrics_ports(args):
    """--metrics-port's port of each process (an empty dict without it)."""
    if not args.metrics_port:
        return {}
    ports = {"reward_server": args.metrics_port, "learner": args.metrics_port + 1}
    for i in range(args.actors):
        ports[f"actor-{i}"] = args.metrics_port + 2 + i
    return ports


def write_prometheus_config(run_dir, ports, scrape_interval="5s"):
    """<run_dir>/prometheus.yml: a Prometheus configuration that scrapes the
    run's endpoints (jobs reward_server, learner, actor) with the alert and
    recording rules of deploy/prometheus/."""
    jobs = {}
    for name, port in ports.items():
        jobs.setdefault(name.split("-")[0], []).append(f"127.0.0.1:{port}")
    lines = ["# Written by ./imca train --metrics-port: prometheus --config.file=<this file>",
             "global:", f"  scrape_interval: {scrape_interval}", f"  evaluation_interval: {scrape_interval}",
             "rule_files:", f"  - {json.dumps(os.path.join(ROOT, 'deploy', 'prometheus', 'rules.yml'))}",
             "scrape_configs:"]
    for job, targets in jobs.items():
        lines += [f"  - job_name: {job}", "    static_configs:",
                  "      - targets: [" + ", ".join(json.dumps(t) for t in targets) + "]"]
    with open(os.path.join(run_dir, "prometheus.yml"), "w") as f:
        f.write("\n".join(lines) + "\n")


def plan(args):
    """({program: the training flags it is started with}, the run's
    config.json): the settings (flags given, the rest filled from the
    binaries' defaults) and, under "resolved", what each binary resolves
    from its flags. Each binary checks its configuration here, before
    anything starts (LaunchError naming the flag)."""
    map_flags = [f"--map={os.path.abspath(args.map)}"] if args.map else []
    flags = {program: program_flags(args, program) + map_flags for program in SCENARIO}
    config = {k: v for k, v in vars(args).items() if k not in ("quiet",)}
    config["map"] = os.path.abspath(args.map or os.path.join(ROOT, "maps", args.scenario + ".txt"))
    config["resolved"] = {program: print_config(args, program, flags[program]) for program in PROGRAMS}
    return flags, config


def run(args):
    run_dir = args.out or os.path.join("runs", datetime.datetime.now().strftime("%Y%m%d-%H%M%S"))
    run_dir = os.path.abspath(run_dir)
    if os.path.exists(os.path.join(run_dir, "metrics.csv")) and not args.resume:
        raise LaunchError(f"--out: '{run_dir}' already holds a run (use --resume to continue it)")
    flags, config = plan(args)  # Nothing is made or started for a configuration the binaries refuse.
    os.makedirs(run_dir, exist_ok=True)
    write_json_atomically(os.path.join(run_dir, "config.json"), config)
    scenario_flags = flags["imca_env"]
    server_tls, actor_tls = secure_flags(run_dir, args) if args.secure else ([], lambda i: [])
    ports = metrics_ports(args)
    metrics_flag = lambda name: [f"--metrics_listen=127.0.0.1:{ports[name]}"] if ports else []
    if ports:
        write_prometheus_config(run_dir, ports)
    services = Services(run_dir, max_restarts=args.max_restarts, stall_seconds=args.stall_seconds)
    rows = []
    interrupted = False
    stop_requested = []
    signal.signal(signal.SIGTERM, lambda *_: stop_requested.append(1))
    try:
        reward_port_file = os.path.join(run_dir, "logs", "reward_server.port")
        learner_port_file = os.path.join(run_dir, "logs", "learner.port")
        for path in (reward_port_file, learner_port_file):
            if os.path.exists(path):
                os.remove(path)
        # A restarted server comes back on the port it had (its clients
        # reconnect there) and from its saved state.
        reward_port = []
        rs = services.start("reward_server", [
            os.path.join(BIN, "reward_server"), f"--port_file={reward_port_file}", *flags["reward_server"],
            f"--snapshot={os.path.join(run_dir, 'reward_snapshot.bin')}", *server_tls, *metrics_flag("reward_server"),
            f"--listen=127.0.0.1:{args.reward_port}"],
            restart_args=lambda: [f"--listen=127.0.0.1:{reward_port[0]}"],
            finished_codes=())  # It never finishes by itself: any exit is a death.
        reward_port.append(services.wait_port("reward_server", rs, reward_port_file))
        learner_port = []
        ln = services.start("learner", [
            os.path.join(BIN, "learner"), f"--port_file={learner_port_file}", *flags["learner"],
            f"--run_dir={run_dir}", f"--trained_log={os.path.join(run_dir, 'logs', 'trained_unrolls.csv')}",
            # Stopped by a signal it did not get from us (exit 143, not 0):
            # restarted, not taken for finished.
            "--signal_exit_code=143"]
            + ([f"--resume={os.path.join(run_dir, 'checkpoints')}"] if args.resume else [])
            + server_tls + metrics_flag("learner") + [f"--listen=127.0.0.1:{args.learner_port}"],
            # From its newest checkpoint (none yet: from scratch).
            restart_args=lambda: [f"--listen=127.0.0.1:{learner_port[0]}", "--resume=", "--auto_resume=true"])
        learner_port.append(services.wait_port("learner", ln, learner_port_file, timeout=60))
        actors = []
        for i in range(args.actors):
            name = f"actor-{i}"
            actors.append(name)
            # A restarted actor (same id, new incarnation) draws other
            # episodes than the dead one: its seed moves with the restart.
            services.start(name, [
                os.path.join(BIN, "actor"), f"--learner=127.0.0.1:{learner_port[0]}",
                f"--reward_server=127.0.0.1:{reward_port[0]}", *flags["actor"],
                f"--actor_id={name}", "--signal_exit_code=143",
                # Its own wait for an ack gives up before the supervisor's.
                f"--ack_timeout_ms={int(args.stall_seconds * 500)}"] + actor_tls(i) + metrics_flag(name)
                + ([f"--trace_file={os.path.join(run_dir, 'credit_trace.csv')}"] if i == 0 else [])
                + [f"--seed={args.seed * 1000 + i + 1}"],
                restart_args=lambda name=name, i=i: [
                    f"--seed={args.seed * 1000 + i + 1 + 1_000_003 * services.restarts[name]}"])
        tty = sys.stderr.isatty()
        last_print = 0.0
        learner_done = False
        while not learner_done:
            if stop_requested:
                raise KeyboardInterrupt
            time.sleep(0.5)
            # The learner exits 0 only with its budget trained; actors exit
            # 0 once it is done.
            learner_done = "learner" in services.supervise(["reward_server", "learner"] + actors)
            services.check_deadlock("learner", actors)
            rows = read_metrics(os.path.join(run_dir, "metrics.csv"))
            if rows and not args.quiet and (tty or time.time() - last_print > 10):
                line = progress_line(rows[-1], args.steps, services.total_restarts())
                print(("\r" + line + "\033[K") if tty else line, end="" if tty else "\n",
                      file=sys.stderr, flush=True)
                last_print = time.time()
    except KeyboardInterrupt:
        interrupted = True
        print("\nimca train: stopping (actors, learner, reward server)...", file=sys.stderr)
    finally:
        # A second Ctrl-C (or a hang-up) must not abandon the children mid-stop.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
        codes = services.stop(names=[n for n, _ in services.procs if n.startswith("actor-")])
        codes.update(services.stop(names=["learner"], timeout=120))
        codes.update(services.stop(names=["reward_server"], timeout=120))
        write_json_atomically(os.path.join(run_dir, "logs", "exit_codes.json"), codes)
        config["restarts"] = dict(services.restarts)
        rows = read_metrics(os.path.join(run_dir, "metrics.csv"))
        # summary.json comes last: its presence means the run folder is complete
        # (./imca experiment counts a cell as finished by it).
        try:
            if rows:
                plot(run_dir, rows, f"{args.scenario} / {args.reward} / credit={args.credit} / "
                                    f"permutation={args.permutation} / seed={args.seed}")
            episode_gif(run_dir, scenario_flags, args.seed)
        finally:
            write_summary(run_dir, config, rows, interrupted)
    if not args.quiet:
        print(file=sys.stderr)
    with open(os.path.join(run_dir, "summary.json")) as f:
        summary = json.load(f)
    print(f"imca train: {summary['env_steps']:,} env steps in {summary['wall_seconds']:.0f} s "
          f"({summary['env_steps_per_sec']:,.0f}/s), final success rate {summary['final_success_rate']:.1%}; "
          f"run folder {run_dir}")
    return 130 if interrupted else 0


def main(argv):
    try:
        return run(parse_args(argv))
    except LaunchError as error:
        print(f"imca train: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
