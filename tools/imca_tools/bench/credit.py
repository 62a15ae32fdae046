"""./imca bench credit: what credit costs end to end, in one run with the same
binaries: env steps/s of ./imca train for each task x reward kind x credit,
the learner's waiting share, and each cell's timeline."""
import os
import statistics
import sys
import time

from .. import binaries, runs
from .common import steady_rate, train


# ./imca bench credit's tasks: (label, ./imca train flags).
CREDIT_TASKS = [("predator_prey (4 agents)", ["--scenario", "predator_prey"]),
                ("coop_nav, 3 agents", ["--scenario", "coop_nav", "--num-agents", "3"])]


def waiting_share(rows):
    """Over the second half of a run: the learner's ms_wait as a share of the
    iterations' wall time (wall_seconds is cumulative)."""
    half = rows[len(rows) // 2:]
    if len(half) < 2:
        return None
    wall_ms = (float(half[-1]["wall_seconds"]) - float(half[0]["wall_seconds"])) * 1e3
    waited = sum(float(r["ms_wait"]) for r in half[1:])
    return waited / wall_ms if wall_ms > 0 else None


SCORE_PHASES = ("lock_wait", "encode", "novelty", "counterfactual", "train", "credit")
ACTOR_PHASES = ("acting", "scoring", "pushing", "choosing_policy")
# The learner's phases after its wait (ms_featurise runs on the pushing
# threads during the wait, so it is not one of them).
LEARNER_TRAIN_COLUMNS = ("ms_values", "ms_gae", "ms_copy", "ms_prepare", "ms_forward", "ms_backward",
                         "ms_optimizer", "ms_publish")


def timeline(out, rows):
    """One cell's timeline, means over the whole run (the status files hold
    totals): ms per learner iteration (wall, wait, train), per unroll of an
    actor by phase, and per Score call by phase (plus its whole handler)."""
    logs = os.path.join(out, "logs")
    wall = float(rows[-1]["wall_seconds"]) * 1e3 / len(rows)
    line = {"iteration": wall,
            "wait": statistics.mean(float(r["ms_wait"]) for r in rows),
            "train": statistics.mean(sum(float(r[c]) for c in LEARNER_TRAIN_COLUMNS if r.get(c)) for r in rows)}
    unrolls, phases = 0, dict.fromkeys(ACTOR_PHASES, 0.0)
    for name in sorted(os.listdir(logs) if os.path.isdir(logs) else []):
        if name.startswith("actor-") and name.endswith(".status.json"):
            status = runs.read_json(os.path.join(logs, name)) or {}
            unrolls += int(status.get("unrolls_pushed", 0))
            for phase in ACTOR_PHASES:
                phases[phase] += float(status.get("phase_seconds", {}).get(phase, 0.0))
    for phase in ACTOR_PHASES:
        line["actor_" + phase] = phases[phase] * 1e3 / max(unrolls, 1)
    reward = runs.read_json(os.path.join(logs, "reward_server.status.json")) or {}
    calls = max(int(reward.get("requests_served", 0)), 1)
    line["score_handler"] = float(reward.get("handler_seconds", 0.0)) * 1e3 / calls
    for phase in SCORE_PHASES:
        line["score_" + phase] = float(reward.get("score_seconds", {}).get(phase, 0.0)) * 1e3 / calls
    return line


def print_timelines(lines):
    """The timeline table of `lines` [(label, timeline())]."""
    print("\n| cell | iteration: wall / wait / train | actor unroll: acting / scoring / pushing / next policy "
          "| Score call: handler (lock wait / encode / novelty / counterfactual / train / credit) |")
    print("|---|---|---|---|")
    for label, t in lines:
        actor = " / ".join(f"{t['actor_' + p]:.0f}" for p in ACTOR_PHASES)
        score = " / ".join(f"{t['score_' + p]:.1f}" for p in SCORE_PHASES)
        print(f"| {label} | {t['iteration']:.0f} / {t['wait']:.0f} / {t['train']:.0f} | {actor} "
              f"| {t['score_handler']:.1f} ({score}) |")
    print("\nms, means over each whole run: per learner iteration; per unroll of an actor (next policy: "
          "waiting for the policy trained on it); per Score call of the reward server.")


def share(fraction):
    """A share as a percentage, or '-' when the run was too short to have one."""
    return "-" if fraction is None else f"{fraction:.0%}"


def run(args, base):
    """The end-to-end credit-cost table (issue: imca credit at shared's price)."""
    rewards = [r for r in args.rewards.split(",") if r]
    credits = [c for c in args.credits.split(",") if c]
    known = binaries.facts()
    for reward in rewards:
        if reward not in known["rewards"]:
            sys.exit(f"imca bench credit: --rewards: '{reward}' is not one of {', '.join(known['rewards'])}")
    for credit in credits:
        if credit not in known["credits"]:
            sys.exit(f"imca bench credit: --credits: '{credit}' is not one of {', '.join(known['credits'])}")
    if args.repeats < 1:
        sys.exit("imca bench credit: --repeats must be >= 1")
    # Repeats run interleaved (every cell once, then again), so that a slow
    # spell of a shared machine falls on every cell alike; each cell reports
    # the run with the median rate, and its timeline.
    runs_of = {}
    for repeat in range(args.repeats):
        for task, flags in CREDIT_TASKS:
            for reward in rewards:
                for credit in credits:
                    slug = f"{flags[1]}{'-' + flags[3] if len(flags) > 2 else ''}-{reward}-{credit}"
                    started = time.time()
                    out = os.path.join(base, slug + (f"-{repeat + 1}" if args.repeats > 1 else ""))
                    _, rows = train(out, ["--steps", str(args.steps), "--reward", reward,
                                          "--credit", credit, "--seed", str(args.seed)] + flags + args.extra)
                    rate, wait = steady_rate(rows), waiting_share(rows)
                    runs_of.setdefault((task, reward, credit), []).append((rate, wait, timeline(out, rows)))
                    print(f"{task} {reward} {credit}" + (f" (run {repeat + 1})" if args.repeats > 1 else "")
                          + f": {rate:,.0f} env steps/s, learner waiting {share(wait)} "
                          f"({time.time() - started:.0f} s)", flush=True)
    results, lines = {}, []
    for (task, reward, credit), done in runs_of.items():
        # The median run (of an even number, the upper of the middle two).
        rate, wait, line = sorted(done, key=lambda run: run[0])[len(done) // 2]
        results[task, reward, credit] = (rate, wait)
        lines.append((f"{task} {reward} {credit}", line))
    print("\n| task | reward | " + " | ".join(credits) + " | imca / shared |")
    print("|---|---|" + "---|" * len(credits) + "---|")
    for task, _ in CREDIT_TASKS:
        for reward in rewards:
            cells = [f"{results[task, reward, c][0]:,.0f} ({share(results[task, reward, c][1])} wait)" for c in credits]
            ratio = (f"{results[task, reward, 'imca'][0] / results[task, reward, 'shared'][0]:.2f}"
                     if "imca" in credits and "shared" in credits else "-")
            print(f"| {task} | {reward} | " + " | ".join(cells) + f" | {ratio} |")
    print(f"\nenv steps/s over each run's second half ({args.steps:,} env steps, seed {args.seed}"
          + (f", the median of {args.repeats} interleaved runs" if args.repeats > 1 else "")
          + (f", flags {' '.join(args.extra)}" if args.extra else "") + "); "
          "(x% wait): the learner's ms_wait share of its iterations' wall time. Run folders: " + base)
    print_timelines(lines)
