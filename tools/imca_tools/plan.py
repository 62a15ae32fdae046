"""What a run of ./imca train is: its flags parsed (a resumed run's recorded
settings restored), each program's flags, and config.json, every value
checked by the binaries themselves (`--print_config`) before anything starts.

./imca experiment and the tests check a configuration the same way, without
starting it.
"""
import argparse
import os
import re

from . import binaries, learner_presets, options, runs, supervisor
from .options import dest


def parser(description=None):
    """./imca train's argument parser: the training options
    (options.all_options, their choices and defaults from the binaries) and the
    launcher's own."""
    p = options.OneLineParser(prog="imca train", description=description,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    known = binaries.facts()
    for flag, programs, keywords in options.all_options(known):
        p.add_argument(flag, default=None, **options.argparse_keywords(flag, programs, keywords, known))
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
    p.add_argument("--max-restarts", type=int, default=supervisor.MAX_RESTARTS,
                   help="restarts of each process before the run gives up (0: none; docs/reliability.md; "
                        f"default: {supervisor.MAX_RESTARTS})")
    p.add_argument("--stall-seconds", type=float, default=supervisor.STALL_SECONDS,
                   help=f"a process with no progress for this long is restarted (default: {supervisor.STALL_SECONDS:g})")
    p.add_argument("--secure", action="store_true",
                   help="mutual TLS and a bearer token on every connection: a throwaway CA, certificates and "
                        "token are made in <run folder>/tls with openssl (docs/security.md)")
    p.add_argument("--learner-preset", choices=learner_presets.names(), default=None,
                   help="a named learner configuration, applied before the other options (which win over it) "
                        "and recorded with them (tools/imca_tools/learner_presets.py; onpolicy: the reference "
                        "MAPPO's, docs/learner.md)")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.add_argument("--actor-score-delays-ms", default="", metavar="MS,MS,...",
                   help="testing: actor i pauses the i-th value before each Score call, changing the order the "
                        "actors' calls arrive in (what --deterministic must not depend on)")
    return p


def recorded_value(p, option, key, value, config_path):
    """A setting config.json recorded, read as its ./imca train option
    (`option`: (flag, argparse keywords), or None for a setting of no option)
    reads it from the command line; p.error names the file and the setting if
    it cannot be: a run folder may have been edited by hand."""
    if option is None:
        return value
    flag, keywords = option
    read_as, choices = keywords.get("type"), keywords.get("choices")
    if read_as is None and choices is None:
        return value
    text = str(value).lower() if isinstance(value, bool) else str(value)
    try:
        read = read_as(text) if read_as is not None else text
    except (TypeError, ValueError, argparse.ArgumentTypeError) as e:
        p.error(f"argument --resume: {config_path}: {key} {value!r} is not a valid {flag} ({e})")
    if choices is not None and read not in choices:
        p.error(f"argument --resume: {config_path}: {key} {value!r} is not one of {', '.join(map(str, choices))}")
    return read


def parse_args(argv, description=None):
    """./imca train's flags (either spelling, options.dashed) -> args, every
    training option set: given, recorded by the run being resumed, or the
    binaries' default for the scenario, algorithm and reward kind. One-line
    SystemExit(2) naming the flag on a bad one; `description` is --help's."""
    p = parser(description)
    known = binaries.facts()
    argv = options.dashed(argv)
    args = p.parse_args(argv)
    if args.learner_preset:  # Its options first: the command line's, later, win.
        args = p.parse_args(learner_presets.argv(args.learner_preset) + argv)
    # What the user gave (or the resumed run recorded): the flags passed on.
    training = [flag for flag, _, _ in options.all_options(known)]
    args.given = sorted(dest(flag) for flag in training if getattr(args, dest(flag)) is not None)
    if args.resume:
        config_path = os.path.join(args.resume, "config.json")
        if not os.path.isfile(config_path) or not os.path.isdir(os.path.join(args.resume, "checkpoints")):
            p.error(f"argument --resume: '{args.resume}' holds no run (config.json and checkpoints/)")
        try:
            saved = runs.read_config(args.resume)
        except (OSError, ValueError) as e:  # Not JSON, or not one object.
            p.error(f"argument --resume: {config_path}: not a run's config ({str(e).splitlines()[0]})")
        given = set(args.given)
        options_by_key = {dest(flag): (flag, options.argparse_keywords(flag, programs, keywords, known))
                          for flag, programs, keywords in options.all_options(known)}
        for key, value in saved.items():
            if key in ("steps", "out", "resume", "reward_port", "learner_port", "given", "resolved"):
                continue
            if hasattr(args, key) and value is not None:
                setattr(args, key, recorded_value(p, options_by_key.get(key), key, value, config_path))
                given.add(key)
        # Every recorded setting is passed on: the run resumes as it ran,
        # whatever the defaults are now.
        args.given = sorted(k for k in given if k in {dest(f) for f in training})
        args.out = args.resume
    # The three choices the other defaults depend on, first.
    for choice in ("scenario", "algo", "reward"):
        if getattr(args, choice) is None:
            setattr(args, choice, known[f"default_{choice}"])
    defaults = options.resolved_defaults(args)
    if args.resume:  # A folder recorded every algorithm's settings before they were told apart.
        args.given = [k for k in args.given if options.held(k, defaults)]
    for flag in training:
        if getattr(args, dest(flag)) is None:
            setattr(args, dest(flag), options.default_of(flag, args, defaults))
    if args.metrics_port and not 1 <= args.metrics_port <= 65535 - 1 - args.actors:
        p.error(f"argument --metrics-port: must be in [1, {65535 - 1 - args.actors}] "
                f"(it takes N .. N+{1 + args.actors}), or 0 for no endpoints")
    try:
        args.score_delays = [int(v) for v in args.actor_score_delays_ms.split(",")] if args.actor_score_delays_ms else []
    except ValueError:
        p.error(f"argument --actor-score-delays-ms: not a list of integers: '{args.actor_score_delays_ms}'")
    if any(not 0 <= d <= 60000 for d in args.score_delays) or len(args.score_delays) > args.actors:
        p.error("argument --actor-score-delays-ms: at most --actors values, each in [0, 60000]")
    if args.max_restarts < 0:
        p.error("argument --max-restarts: must be >= 0")
    if args.stall_seconds < 10:
        # An actor waiting for a policy refreshes its status once per long
        # poll (up to 5 s); a shorter limit would restart healthy waiters.
        p.error("argument --stall-seconds: must be >= 10")
    if args.map and not os.path.isfile(args.map):
        p.error(f"argument --map: no such file '{args.map}'")
    return args


def print_config(args, program, flags):
    """`program --print_config` with `flags` (binaries.print_config); a
    refusal is a LaunchError naming the ./imca train flag."""
    try:
        return binaries.print_config(program, flags)
    except binaries.Refused as refused:
        message = str(refused)
        # The given option the message names first (past its "program: --flag value:" context).
        reason = re.sub(r"^\w+: (--\w+ \S+: )?", "", message)
        named = []
        for flag, programs, _ in options.all_options():
            name = programs.get(program)
            found = re.search(rf"(?<!\w){re.escape(name)}(?!\w)", reason) if name else None
            if found and dest(flag) in args.given:
                named.append((found.start(), flag))
        raise binaries.LaunchError(f"argument {min(named)[1]}: {message}" if named else message) from None


def plan(args):
    """({program: the training flags it is started with}, the run's
    config.json): the settings (flags given, the rest filled from the
    binaries' defaults) and, under "resolved", what each binary resolves
    from its flags. Each binary checks its configuration here, before
    anything starts (LaunchError naming the flag)."""
    map_flags = [f"--map={os.path.abspath(args.map)}"] if args.map else []
    flags = {program: options.program_flags(args, program) + map_flags for program in options.SCENARIO}
    config = {k: v for k, v in vars(args).items() if k not in ("quiet",)}
    config["map"] = os.path.abspath(args.map or os.path.join(binaries.ROOT, "maps", args.scenario + ".txt"))
    config["resolved"] = {program: print_config(args, program, flags[program]) for program in binaries.PROGRAMS}
    return flags, config

