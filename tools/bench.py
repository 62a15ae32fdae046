#!/usr/bin/python3
"""./imca bench speed|env|reward|learn: benchmarks run by hand (never in CI).

speed  component ceilings (bench_speed) and end-to-end training throughput,
       with the ratio end-to-end / learner-only.
env    joint env steps/s of every scenario on one core (vectorised).
reward Score throughput for count, rnd, sf with 2 and 4 agents; counterfactual share.
learn  the learning benchmark: credit none/shared/independent/imca x 3 seeds
       (--scenario, --reward; further training flags after --); final success
       rate, env steps to 80% and 90%, and imca's credit diagnostics.
"""
import argparse
import csv
import datetime
import json
import os
import statistics
import subprocess
import sys

ROOT = os.environ.get("IMCA_ROOT", os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("IMCA_BIN", os.path.join(ROOT, "build", "bin"))
LAUNCH = [sys.executable, os.path.join(ROOT, "tools", "launch.py")]


def train(out, extra):
    r = subprocess.run(LAUNCH + ["--out", out, "--quiet"] + extra, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"imca bench: training failed: {r.stderr.strip().splitlines()[-1] if r.stderr.strip() else r.returncode}")
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    with open(os.path.join(out, "metrics.csv")) as f:
        rows = list(csv.DictReader(f))
    return summary, rows


def steady_rate(rows):
    """Env steps/s over the second half of a run (start-up excluded)."""
    mid = rows[len(rows) // 2]
    last = rows[-1]
    return (int(last["env_steps"]) - int(mid["env_steps"])) / (float(last["wall_seconds"]) - float(mid["wall_seconds"]))


def speed(args, base):
    print("== component ceilings (medians of timed rounds) ==", flush=True)
    r = subprocess.run([os.path.join(BIN, "bench_speed"), str(args.rounds)], capture_output=True, text=True,
                       env=dict(os.environ, OMP_WAIT_POLICY="passive"))
    print(r.stdout, end="")
    figures = dict(line.split() for line in r.stdout.splitlines() if line.strip())
    print("== end-to-end training (./imca train defaults) ==", flush=True)
    rates = []
    for i in range(args.repeats):
        _, rows = train(os.path.join(base, f"e2e-{i}"), ["--steps", str(args.steps)])
        rates.append(steady_rate(rows))
        print(f"end_to_end_steps_per_sec run {i}: {rates[-1]:.0f}", flush=True)
    e2e = statistics.median(rates)
    learner = float(figures["learner_steps_per_sec_1thread"])
    print(f"end_to_end_steps_per_sec {e2e:.0f}")
    print(f"ratio end_to_end / learner_only(1 thread) {e2e / learner:.2f}")


def env_bench(args, base):
    r = subprocess.run([os.path.join(BIN, "bench_env"), str(args.rounds)], capture_output=True, text=True)
    print(r.stdout, end="")
    if r.returncode != 0:
        sys.exit(f"imca bench: bench_env failed: {r.stderr.strip()}")


def reward_bench(args, base):
    r = subprocess.run([os.path.join(BIN, "bench_reward"), str(args.rounds)], capture_output=True, text=True,
                       env=dict(os.environ, OMP_WAIT_POLICY="passive"))
    print(r.stdout, end="")
    if r.returncode != 0:
        sys.exit(f"imca bench: bench_reward failed: {r.stderr.strip()}")


def tail_mean(rows, key, fraction=0.25):
    """Mean of a metrics column over the last quarter of a run (None if absent)."""
    values = [float(r[key]) for r in rows[-max(1, int(len(rows) * fraction)):] if r.get(key) not in (None, "")]
    return statistics.mean(values) if values else None


def learn(args, base):
    modes = args.credits.split(",")
    seeds = [int(s) for s in args.seeds.split(",")]
    results = {}
    for credit in modes:
        for seed in seeds:
            out = os.path.join(base, f"{credit}-seed{seed}")
            summary, rows = train(out, ["--scenario", args.scenario, "--reward", args.reward, "--credit", credit,
                                        "--seed", str(seed), "--steps", str(args.steps)] + args.extra)
            results[(credit, seed)] = (summary, rows)
            print(f"{credit:12s} seed {seed}: final success {summary['final_success_rate']:.1%}, "
                  f"steps to 80% {summary['steps_to_80pct_success']}, to 90% {summary['steps_to_90pct_success']}, "
                  f"{summary['env_steps_per_sec']:.0f} steps/s", flush=True)
    steps = lambda xs: " / ".join("-" if x is None else f"{x / 1e6:.2f}M" for x in xs)
    print(f"\n{args.scenario} + {args.reward}, {args.steps:,} env steps, seeds {args.seeds}"
          + (f", flags {' '.join(args.extra)}" if args.extra else ""))
    print("| credit | final success (per seed) | mean | env steps to 80% | env steps to 90% "
          "| last-quarter mean: R_i, abs r^a, max p^a |")
    print("|---|---|---|---|---|---|")
    for credit in modes:
        runs = [results[(credit, s)] for s in seeds]
        finals = [summary["final_success_rate"] for summary, _ in runs]
        diag = []
        for key in ("global_reward", "contribution_abs", "share_max"):
            values = [tail_mean(rows, key) for _, rows in runs]
            diag.append("-" if None in values else f"{statistics.mean(values):.4g}")
        print(f"| {credit} | {' / '.join(f'{x:.0%}' for x in finals)} | {statistics.mean(finals):.0%} | "
              f"{steps(summary['steps_to_80pct_success'] for summary, _ in runs)} | "
              f"{steps(summary['steps_to_90pct_success'] for summary, _ in runs)} | {', '.join(diag)} |")
    print(f"\nrun folders: {base}")


def main(argv):
    p = argparse.ArgumentParser(prog="imca bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="what", required=True)
    s = sub.add_parser("speed")
    s.add_argument("--rounds", type=int, default=7)
    s.add_argument("--repeats", type=int, default=3)
    s.add_argument("--steps", type=int, default=600_000)
    e = sub.add_parser("env")
    e.add_argument("--rounds", type=int, default=7)
    rw = sub.add_parser("reward")
    rw.add_argument("--rounds", type=int, default=5)
    l = sub.add_parser("learn")
    l.add_argument("--credits", default="none,shared,independent,imca")
    l.add_argument("--seeds", default="1,2,3")
    l.add_argument("--steps", type=int, default=2_000_000)
    l.add_argument("--scenario", default="coop_nav")
    l.add_argument("--reward", default="count")
    l.add_argument("extra", nargs="*", help="after --: more ./imca train flags, e.g. -- --beta 0.1")
    args = p.parse_args(argv)
    if args.what != "learn":
        args.extra = []
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    base = os.path.join(ROOT, "runs", f"bench-{args.what}-"
                        + (f"{args.scenario}-{args.reward}-" if args.what == "learn" else "") + stamp)
    os.makedirs(base, exist_ok=True)
    {"speed": speed, "env": env_bench, "reward": reward_bench, "learn": learn}[args.what](args, base)


if __name__ == "__main__":
    main(sys.argv[1:])
