"""The ./imca train flag vocabulary: each option, the binary flag(s) it sets,
and how a given option becomes those flags.

No values live here: an option not given is not passed on, so the binaries'
defaults (`<binary> --list`, binaries.facts()) are the one definition; help
texts quote them from there.
"""
import argparse

from . import binaries


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
# binary's flag}, argparse keywords; choices as a function of the binaries'
# --list). FIXED_OPTIONS are those that span programs, are renamed, or are
# not a binary's listed setting; every other setting the learner and reward
# server list (--list: learner_settings, reward_settings: name, type, help,
# choices) is an option under its own name, dashed (listed_options), so that a
# setting declared once in C++ is an option without being restated here. Each
# is passed on only when given (or recorded by a run being resumed), so that
# the binaries' defaults, in C++ beside what they configure (and the
# scenario's, algorithm's and reward kind's differences beside their specs),
# are the one definition: `<binary> --list` prints them per scenario, plan's
# parse_args fills what was not given from there, for the record and the
# progress line, and --help quotes them (default_text). Values are checked by
# the binaries (`--print_config`), not here. docs/learner.md.
SCENARIO = ("reward_server", "learner", "actor", "imca_env")  # The env tool renders the episode GIF.
FIXED_OPTIONS = [
    ("--scenario", {p: "scenario" for p in SCENARIO}, dict(choices=lambda k: k["scenarios"])),
    ("--num-agents", {p: "num_agents" for p in SCENARIO}, dict(type=int, help="agents")),
    ("--step-limit", {p: "step_limit" for p in SCENARIO}, dict(type=int, help="episode step limit")),
    ("--view-radius", {p: "view_radius" for p in SCENARIO}, dict(type=int, help="partial observation radius (0: full)")),
    ("--door-timer", {p: "door_timer" for p in SCENARIO},
     dict(type=int, help="door scenarios: EDTI's door-open interval doi (docs/scenarios.md)")),
    ("--reward-threads", {"reward_server": "threads"},
     dict(type=positive_int, help="rnd, sf: the reward server's LibTorch intra-op threads")),
    ("--snapshot-every", {"reward_server": "snapshot_every"},
     dict(type=int, help="reward server snapshot interval in s (count kinds also journal every increment)")),
    ("--seed", {"reward_server": "seed", "learner": "seed"},
     dict(type=int, help="seed of the run (actor i acts with seed * 1000 + i + 1)")),
    ("--algo", {"learner": "algo", "actor": "algo"},
     dict(choices=lambda k: k["algos"],
          help="the learner's algorithm (docs/learner.md)")),
    ("--deterministic", {"reward_server": "deterministic", "learner": "deterministic"},
     dict(type=boolean, metavar="BOOL",
          help="a run that replays bit for bit: the learner adds each batch in (actor, sequence) order and the "
               "reward server applies each policy version's updates in that order (needs --sync true; "
               "docs/learner.md)")),
    ("--sync", {"learner": "synchronous"},
     dict(type=boolean, metavar="BOOL",
          help="synchronous collection: every iteration trains on the policy it starts from, each actor acting "
               "batch steps / actors of it")),
    ("--learner-threads", {"learner": "threads"}, dict(type=positive_int,
                                                       help="LibTorch threads of each learner pass")),
    ("--steps", {"learner": "steps"}, dict(type=positive_int, help="budget in joint env steps")),
    ("--actors", {"learner": "actors"}, dict(type=positive_int, help="actor processes")),
    ("--batch-steps", {"learner": "batch_steps"}, dict(type=positive_int,
                                                       help="joint env steps per PPO iteration")),
    ("--envs-per-actor", {"actor": "envs"}, dict(type=positive_int, help="environments of each actor")),
    ("--unroll-length", {"actor": "unroll_length"}, dict(type=positive_int,
                                                         help="steps per unroll")),
]


# The programs whose --list rows (learner_settings, reward_settings) are
# options of ./imca train under their own names, dashed: each setting a binary
# declares (name, type, help, choices) is an option without being restated
# here. FIXED_OPTIONS above are the ones that span programs, are renamed or are
# checked here too.
LISTED = {"learner": "learner_settings", "reward_server": "reward_settings"}
_TYPES = {"int": dict(type=int), "float": dict(type=float), "string": {}, "bool": dict(type=boolean, metavar="BOOL")}


def listed_options(known):
    """The options from the binaries' setting rows that FIXED_OPTIONS does
    not already map (by the binary's flag name), in --list order."""
    mapped = {(program, name) for _, programs, _ in FIXED_OPTIONS for program, name in programs.items()}
    out = []
    for program, key in LISTED.items():
        for row in known[key]:
            if (program, row["name"]) in mapped:
                continue
            keywords = dict(_TYPES.get(row["type"], {}), help=row["help"])
            if row["type"] == "enum":
                keywords["choices"] = row["choices"]
            out.append(("--" + row["name"].replace("_", "-"), {program: row["name"]}, keywords))
    return out


def all_options(known=None):
    """Every training option of ./imca train: FIXED_OPTIONS, then the
    binaries' listed settings (listed_options). Raises ValueError if two map
    to one ./imca flag."""
    found = FIXED_OPTIONS + listed_options(known or binaries.facts())
    flags = [flag for flag, _, _ in found]
    twice = sorted({flag for flag in flags if flags.count(flag) > 1})
    if twice:
        raise ValueError(f"./imca train options named twice: {', '.join(twice)} (rename one in FIXED_OPTIONS)")
    return found


def programs_of(flag):
    """{program: the binary's flag} of ./imca train option `flag`."""
    return next(programs for f, programs, _ in all_options() if f == flag)


def learner_choices(known, name):
    """The names the learner's enum setting `name` takes (its --list row)."""
    return next(row["choices"] for row in known["learner_settings"] if row["name"] == name)


def dest(flag):
    return flag[2:].replace("-", "_")


def argparse_keywords(flag, programs, keywords, known):
    """An all_options entry's argparse keywords with its choices from `known`
    (binaries.facts()) and its default, as the binaries define it, in its help."""
    keywords = dict(keywords)
    if keywords.get("type") is boolean:  # The bare form too, as the binaries take it: --x is --x true.
        keywords.setdefault("nargs", "?")
        keywords.setdefault("const", True)
    if callable(keywords.get("choices")):
        keywords["choices"] = keywords["choices"](known)
    text = default_text(flag, programs, known)
    if text is not None:
        keywords["help"] = " ".join(filter(None, [keywords.get("help"), f"(default: {text})"]))
    return keywords


def _fmt(value):
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _summary(values, default_key):
    """{key: value} as "V; W for k1, k2": the most common value (the
    default key's on a tie), then the others with the keys that have them."""
    counts = {}
    for value in values.values():
        counts[_fmt(value)] = counts.get(_fmt(value), 0) + 1
    base = max(counts, key=lambda v: (counts[v], v == _fmt(values[default_key])))
    others = {}
    for key, value in values.items():
        if _fmt(value) != base:
            others.setdefault(_fmt(value), []).append(key)
    return "; ".join([base] + [f"{v} for {', '.join(keys)}" for v, keys in others.items()])


def default_text(flag, programs, known):
    """The binaries' default of an option, per reward kind, algorithm or
    scenario where it differs (from `known`, binaries.facts()); None if
    --list does not say."""
    program, name = next(iter(programs.items()))
    if dest(flag) in ("scenario", "algo", "reward"):
        return known[f"default_{dest(flag)}"]
    if "imca_env" in programs:
        return "the scenario's"  # Its parameters (num_agents, ...) are in its spec, not in --list.
    if program == "reward_server":
        table, kind, scenario = known["reward_defaults"], known["default_reward"], known["default_scenario"]
        return _two_level_text(table, name, kind, scenario, both=lambda: _scaled_text(table, name, kind, scenario))
    if program == "actor":
        values = {s: d.get(name) for s, d in known["actor_defaults"][known["default_algo"]].items()}
        return None if None in values.values() else _summary(values, known["default_scenario"])
    if program == "learner":
        return _two_level_text(known["learner_defaults"], name, known["default_algo"], known["default_scenario"],
                               both=lambda: "the scenario's and algorithm's")
    return None


def _two_level_text(table, name, outer_default, scenario_default, both):
    """The default text of setting `name` in a table {algorithm or reward
    kind: {scenario: defaults}}: by the outer key, or by scenario, where only
    one of them matters; else both(). None if a default does not hold the
    setting."""
    table = {o: by for o, by in table.items() if all(d.get(name) is not None for d in by.values())}
    if not table:  # No algorithm or reward kind holds it.
        return None
    outer_default = outer_default if outer_default in table else next(iter(table))
    if all(len({_fmt(d[name]) for d in table[o].values()}) == 1 for o in table):  # By the outer key only.
        return _summary({o: next(iter(table[o].values()))[name] for o in table}, outer_default)
    if all(len({_fmt(table[o][s][name]) for o in table}) == 1 for s in table[outer_default]):  # By scenario only.
        return _summary({s: d[name] for s, d in table[outer_default].items()}, scenario_default)
    return both()


def _scaled_text(table, name, kind_default, scenario_default):
    """A reward kind's default that scenarios scale (the bonus_scale of
    common/env/env.h) as "0.5; 1 for eiti, edti; times 0.001 on pass_cmae, ...";
    "the reward kind's and scenario's" where it is not one scale per scenario."""
    base = {k: by_scenario[scenario_default][name] for k, by_scenario in table.items()}
    if not all(isinstance(v, (int, float)) and v for v in base.values()):
        return "the reward kind's and scenario's"
    scales = {}
    for scenario in table[kind_default]:
        ratios = {_fmt(table[k][scenario][name] / base[k]) for k in table}
        if len(ratios) != 1:
            return "the reward kind's and scenario's"
        if ratios != {"1"}:
            scales.setdefault(ratios.pop(), []).append(scenario)
    return "; ".join([_summary(base, kind_default)] + [f"times {r} on {', '.join(s)}" for r, s in scales.items()])


def resolved_defaults(args):
    """{program: {binary flag: default}} for the scenario, algorithm and
    reward kind of args: what `<program> --list` resolves."""
    known = binaries.facts()
    return {"reward_server": known["reward_defaults"][args.reward][args.scenario],
            "learner": known["learner_defaults"][args.algo][args.scenario],
            "actor": known["actor_defaults"][args.algo][args.scenario]}


def default_of(flag, args, defaults=None):
    """The binaries' default of option `flag` for the scenario, algorithm and
    reward kind of args (None for a scenario parameter: the scenario's own)."""
    program, name = next(iter(programs_of(flag).items()))
    return (defaults or resolved_defaults(args)).get(program, {}).get(name)


class OneLineParser(argparse.ArgumentParser):
    """Flag errors as one line naming the flag (no usage dump)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: {message}\n")


def dashed(argv):
    """argv with every flag name spelled with hyphens: ./imca takes the
    binaries' own spelling (--door_timer) as --door-timer everywhere and
    documents the hyphens. Values and what follows a bare "--" are untouched."""
    out = list(argv)
    for i, word in enumerate(out):
        if word == "--":
            break
        if word.startswith("--"):
            name, eq, value = word.partition("=")
            out[i] = "--" + name[2:].replace("_", "-") + eq + value
    return out


def program_flags(args, program):
    """The training flags ./imca train passes to `program`: those of the
    options given (the rest are the binary's defaults), in all_options order."""
    flags = []
    for flag, programs, _ in all_options():
        name = programs.get(program)
        if name is None or dest(flag) not in args.given:
            continue
        value = getattr(args, dest(flag))
        flags.append(f"--{name}={str(value).lower() if isinstance(value, bool) else value}")
    if program == "learner" and args.reward == "edti":
        flags.append("--edti=true")  # EDTI's value of interaction: the learner's half of --reward edti.
    return sorted(flags)


def held(option_dest, defaults):
    """Whether the algorithm and reward kind whose `defaults` (resolved_defaults)
    these are hold the setting of ./imca train option `option_dest`: a listed
    setting of another algorithm or kind is not (a run recorded every setting
    before they were told apart)."""
    for flag, programs, _ in listed_options(binaries.facts()):
        if dest(flag) == option_dest:
            return all(name in defaults[program] for program, name in programs.items())
    return True  # One of FIXED_OPTIONS: every run's.

