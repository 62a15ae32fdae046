"""./imca bench learn: the learning benchmark (credit modes x seeds), and with
--variants an ablation (variant x credit x seed); --out resumes."""
import csv
import json
import os
import statistics
import sys

from .. import binaries, runs, stats
from ..runner import config_conflict
from .common import millions, median_reached, to_90, train


def finished_run(out, budget):
    """(summary, rows) of a run folder that reached `budget` uninterrupted, else None."""
    summary = runs.finished_summary(out, budget)
    if summary is None:
        return None
    with open(os.path.join(out, "metrics.csv")) as f:
        return summary, list(csv.DictReader(f))


def tail_mean(rows, key, fraction=0.25):
    """Mean of a metrics column over the last quarter of a run (None if absent)."""
    values = [float(r[key]) for r in rows[-max(1, int(len(rows) * fraction)):] if r.get(key) not in (None, "")]
    return statistics.mean(values) if values else None


def load_variants(path):
    """[(name, [train flags])] from a JSON object {name: {flag: value}}, in file order."""
    try:
        with open(path) as f:
            spec = json.load(f)
    except (OSError, ValueError) as error:
        sys.exit(f"imca bench: --variants {path}: {error}")
    if not isinstance(spec, dict) or not spec:
        sys.exit(f"imca bench: --variants {path}: must be a non-empty object of name -> flags")
    variants = []
    for name, flags in spec.items():
        if not isinstance(flags, dict) or not name.replace("_", "").replace("-", "").isalnum():
            sys.exit(f"imca bench: --variants {path}: variant '{name}' must be a word mapping to an object of flags")
        argv = []
        for key, value in flags.items():
            argv += [f"--{key.replace('_', '-')}", str(value).lower() if isinstance(value, bool) else str(value)]
        variants.append((name, argv))
    return variants


def ablation_table(args, variants, modes, seeds, results):
    """Per variant and credit: env steps to 90% over seeds (median with a
    seed that never got there as infinitely late, and IQM with it counted as
    the budget: a lower bound then), the probability that a run of the
    variant gets there sooner than a run of the first variant (P(X < Y), a
    tie counting one half: stats.probability_of_improvement on the negated
    steps), and what the arm cost in wall-clock."""
    window = binaries.facts()["success_window"]  # The learner's success window.
    first = variants[0][0]
    print(f"\n{args.scenario} + {args.reward}, {args.steps:,} env steps, seeds {args.seeds}; success over the "
          f"last {window} training episodes (as marlbenchmark/on-policy) and over the last {window} evaluation episodes; "
          f"P(sooner) against {first}")
    print("| variant | credit | env steps to 90%, training episodes: median (per seed) | IQM | P(sooner) | reached "
          "| wall-clock to 90%: median | env steps to 90%, evaluation: median | final success | env steps/s "
          "| arm wall-clock |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    def steps_to_90(name, credit):  # Per seed, a seed that never got there at the budget.
        return stats.steps_or_budget([to_90(results[(name, credit, s)][1], "train_success_rate")[0] for s in seeds],
                                     args.steps)

    for name, _ in variants:
        for credit in modes:
            trials = [results[(name, credit, s)] for s in seeds]
            train = [to_90(rows, "train_success_rate") for _, rows in trials]
            evals = [to_90(rows, "success_rate")[0] for _, rows in trials]
            reached = sum(1 for steps, _ in train if steps is not None)
            wall = median_reached([w for _, w in train])
            mine = steps_to_90(name, credit)
            sooner = stats.probability_of_improvement([[-x for x in mine]], [[-x for x in steps_to_90(first, credit)]])
            print(f"| {name} | {credit} | {millions(median_reached([x for x, _ in train]))} "
                  f"({' / '.join(millions(x) for x, _ in train)}) | {millions(stats.iqm(mine))} | {sooner:.2f} "
                  f"| {reached}/{len(seeds)} "
                  f"| {'-' if wall is None else f'{wall:.1f} s'} | {millions(median_reached(evals))} "
                  f"| {statistics.mean(s['final_train_success_rate'] for s, _ in trials):.0%} "
                  f"| {statistics.median(s['env_steps_per_sec'] for s, _ in trials):,.0f} "
                  f"| {sum(s['wall_seconds'] for s, _ in trials):,.0f} s |")


def run(args, base):
    modes = args.credits.split(",")
    seeds = [int(s) for s in args.seeds.split(",")]
    variants = load_variants(args.variants) if args.variants else [("default", [])]
    planned = []  # (variant, credit, seed, run folder, ./imca train flags)
    for name, variant_flags in variants:
        for credit in modes:
            for seed in seeds:
                planned.append((name, credit, seed,
                                os.path.join(base, (f"{name}-" if args.variants else "") + f"{credit}-seed{seed}"),
                                ["--scenario", args.scenario, "--reward", args.reward, "--credit", credit,
                                 "--seed", str(seed), "--steps", str(args.steps)] + variant_flags + args.extra))
    # Before anything runs: a finished run of other settings (other flags, or
    # defaults changed since) would sit in the table as if run with these.
    for _, _, _, out, flags in planned:
        if finished_run(out, args.steps) is None:
            continue
        try:
            conflict = config_conflict(out, flags + ["--out", out])
        except ValueError as error:
            sys.exit(f"imca bench: {error}")
        if conflict:
            sys.exit(f"imca bench: {out} was run with {conflict}; use another --out, or the flags it ran with "
                     f"(its config.json)")
    results = {}
    for name, credit, seed, out, flags in planned:
        done = finished_run(out, args.steps)
        if done is None:
            done = train(out, flags)
        summary, rows = done
        results[(name, credit, seed)] = done
        steps90, wall90 = to_90(rows, "train_success_rate")
        print(f"{name:12s} {credit:12s} seed {seed}: final success {summary['final_success_rate']:.1%}, "
              f"to 90% (training episodes) {steps90} steps / {wall90} s, "
              f"to 90% (evaluation) {summary['steps_to_90pct_success']}, "
              f"{summary['env_steps_per_sec']:.0f} steps/s", flush=True)
    ablation_table(args, variants, modes, seeds, results)
    if args.variants:
        print(f"\nrun folders: {base}")
        return
    results = {(credit, seed): results[("default", credit, seed)] for credit in modes for seed in seeds}
    steps = lambda xs: " / ".join(millions(x) for x in xs)
    print(f"\n{args.scenario} + {args.reward}, {args.steps:,} env steps, seeds {args.seeds}"
          + (f", flags {' '.join(args.extra)}" if args.extra else ""))
    print("| credit | final success (per seed) | mean | env steps to 80% | env steps to 90% "
          "| last-quarter mean: R_i, abs r^a, max p^a |")
    print("|---|---|---|---|---|---|")
    for credit in modes:
        trials = [results[(credit, s)] for s in seeds]
        finals = [summary["final_success_rate"] for summary, _ in trials]
        diag = []
        for key in ("global_reward", "contribution_abs", "share_max"):
            values = [tail_mean(rows, key) for _, rows in trials]
            diag.append("-" if None in values else f"{statistics.mean(values):.4g}")
        print(f"| {credit} | {' / '.join(f'{x:.0%}' for x in finals)} | {statistics.mean(finals):.0%} | "
              f"{steps(summary['steps_to_80pct_success'] for summary, _ in trials)} | "
              f"{steps(summary['steps_to_90pct_success'] for summary, _ in trials)} | {', '.join(diag)} |")
    print(f"\nrun folders: {base}")
