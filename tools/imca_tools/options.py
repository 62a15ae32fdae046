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
# --list). Each is passed on only when given (or recorded by a run being
# resumed), so that the binaries' defaults, in C++ beside what they configure
# (and the scenario's and reward kind's differences beside their specs), are
# the one definition: `<binary> --list` prints them per scenario, plan's
# parse_args fills what was not given from there, for the record and the
# progress line, and --help quotes them (default_text). Values are checked by
# the binaries (`--print_config`), not here. docs/learner.md.
SCENARIO = ("reward_server", "learner", "actor", "imca_env")  # The env tool renders the episode GIF.
OPTIONS = [
    ("--scenario", {p: "scenario" for p in SCENARIO}, dict(choices=lambda k: k["scenarios"])),
    ("--num-agents", {p: "num_agents" for p in SCENARIO}, dict(type=int, help="agents")),
    ("--step-limit", {p: "step_limit" for p in SCENARIO}, dict(type=int, help="episode step limit")),
    ("--view-radius", {p: "view_radius" for p in SCENARIO}, dict(type=int, help="partial observation radius (0: full)")),
    ("--door-timer", {p: "door_timer" for p in SCENARIO},
     dict(type=int, help="door scenarios: EDTI's door-open interval doi (docs/scenarios.md)")),
    ("--reward", {"reward_server": "reward"}, dict(choices=lambda k: list(k["rewards"]), help="global novelty kind")),
    ("--credit", {"reward_server": "credit"}, dict(choices=lambda k: k["credits"],
                                                   help="credit mode")),
    ("--permutation", {"reward_server": "permutation"}, dict(choices=lambda k: k["permutations"])),
    ("--beta", {"reward_server": "beta"}, dict(type=float, help="coefficient of the global bonus")),
    ("--eta", {"reward_server": "eta"}, dict(type=float, help="eiti, edti: coefficient of the decentralised curiosity")),
    ("--beta-t", {"reward_server": "beta_t"}, dict(type=float, help="eiti: coefficient of the summed influence")),
    ("--temperature", {"reward_server": "temperature"}, dict(type=float, help="softmax temperature of the shares")),
    ("--reward-threads", {"reward_server": "threads"},
     dict(type=positive_int, help="rnd, sf: the reward server's LibTorch intra-op threads")),
    ("--snapshot-every", {"reward_server": "snapshot_every"},
     dict(type=int, help="reward server snapshot interval in s (count kinds also journal every increment)")),
    ("--seed", {"reward_server": "seed", "learner": "seed"},
     dict(type=int, help="seed of the run (actor i acts with seed * 1000 + i + 1)")),
    ("--algo", {"learner": "algo", "actor": "algo"},
     dict(choices=lambda k: k["algos"],
          help="mappo (on-policy PPO), maddpg (off-policy) or cmae (tabular; docs/learner.md)")),
    ("--steps", {"learner": "steps"}, dict(type=positive_int, help="budget in joint env steps")),
    ("--actors", {"learner": "actors"}, dict(type=positive_int, help="actor processes")),
    ("--batch-steps", {"learner": "batch_steps"}, dict(type=positive_int,
                                                       help="joint env steps per PPO iteration")),
    ("--max-batch-mb", {"learner": "max_batch_mb"},
     dict(type=positive_int, help="learner's cap on an iteration's feature memory (docs/learner.md)")),
    ("--lr", {"learner": "lr"}, dict(type=float, help="Adam learning rate")),
    ("--entropy-coef", {"learner": "entropy_coef"}, dict(type=float, help="entropy bonus coefficient")),
    ("--intrinsic-coef", {"learner": "intrinsic_coef"}, dict(type=float, help="weight of the intrinsic advantage")),
    ("--separate-optimizers", {"learner": "separate_optimizers"},
     dict(type=boolean, metavar="BOOL",
          help="one Adam and grad clip each for actor and critic, false: one over both")),
    ("--deterministic", {"reward_server": "deterministic", "learner": "deterministic"},
     dict(type=boolean, metavar="BOOL",
          help="a run that replays bit for bit: the learner adds each batch in (actor, sequence) order and the "
               "reward server applies each policy version's updates in that order (needs --sync true; "
               "docs/learner.md)")),
    ("--sync", {"learner": "synchronous"},
     dict(type=boolean, metavar="BOOL",
          help="synchronous collection: every iteration trains on the policy it starts from, each actor acting "
               "batch steps / actors of it")),
    ("--checkpoint-seconds", {"learner": "checkpoint_seconds"},
     dict(type=float, help="learner checkpoint interval: what a learner restart loses at most")),
    ("--objective", {"learner": "objective"}, dict(choices=lambda k: learner_choices(k, "objective"),
                                                   help="PPO clip against the behaviour policy or a recomputed proximal one")),
    ("--layer-norm", {"learner": "layer_norm"}, dict(type=boolean, metavar="BOOL",
                                                     help="LayerNorm on input and hidden layers")),
    ("--value-heads", {"learner": "value_heads"}, dict(type=int, help="2: extrinsic + intrinsic heads; 1: one")),
    ("--critic-input", {"learner": "critic_input"}, dict(choices=lambda k: learner_choices(k, "critic_input"), help="centralised critic's input")),
    ("--time-limit", {"learner": "time_limit"}, dict(choices=lambda k: learner_choices(k, "time_limit"), help="the step limit in the returns")),
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
    ("--cmae-episodes", {"learner": "cmae_episodes"},
     dict(type=int, help="cmae: episodes over which acting moves to the exploitation tables")),
    ("--cmae-gamma", {"learner": "cmae_gamma"}, dict(type=float, help="cmae: discount of its Q-tables")),
    ("--cmae-explore-lr", {"learner": "cmae_explore_lr"}, dict(type=float, help="cmae: exploration tables' rate")),
    ("--cmae-exploit-lr", {"learner": "cmae_exploit_lr"}, dict(type=float, help="cmae: exploitation tables' rate")),
    ("--cmae-replay", {"learner": "cmae_replay"}, dict(type=positive_int, help="cmae: replay capacity")),
    ("--cmae-goal-samples", {"learner": "cmae_goal_samples"},
     dict(type=positive_int, help="cmae: replay states a goal is chosen among")),
    ("--cmae-batch", {"learner": "cmae_batch"}, dict(type=int, help="cmae: transitions of an exploitation fit")),
    ("--cmae-recip-t", {"learner": "cmae_recip_t"},
     dict(type=float, help="cmae: reciprocal temperature of the restricted-space choice")),
    ("--cmae-tracked", {"learner": "cmae_tracked"},
     dict(type=positive_int, help="cmae: restricted spaces weighed at each choice")),
    ("--cmae-max-table-mb", {"learner": "cmae_max_table_mb"},
     dict(type=positive_int, help="cmae: refuse a scenario whose tables could outgrow this")),
    ("--envs-per-actor", {"actor": "envs"}, dict(type=positive_int, help="environments of each actor")),
    ("--unroll-length", {"actor": "unroll_length"}, dict(type=positive_int,
                                                         help="steps per unroll")),
]


PROGRAMS_OF = {flag: programs for flag, programs, _ in OPTIONS}


def learner_choices(known, name):
    """The names the learner's enum setting `name` takes (its --list row)."""
    return next(row["choices"] for row in known["learner_settings"] if row["name"] == name)


def dest(flag):
    return flag[2:].replace("-", "_")


def argparse_keywords(flag, programs, keywords, known):
    """An OPTIONS entry's argparse keywords with its choices from `known`
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
        values = {s: d.get(name) for s, d in known["actor_defaults"]["mappo"].items()}
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
    env/env.h) as "0.5; 1 for eiti, edti; times 0.001 on pass_cmae, ...";
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
    program, name = next(iter(PROGRAMS_OF[flag].items()))
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

