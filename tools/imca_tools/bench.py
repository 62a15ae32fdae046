"""./imca bench speed|env|reward|credit|learn|soak|drill|python: benchmarks run by hand (never in CI).

speed  component ceilings (bench_speed) and end-to-end training throughput,
       with the ratio end-to-end / learner-only.
env    joint env steps/s of every scenario on one core (vectorised).
reward Score throughput for count, rnd, sf with 2 and 4 agents; counterfactual share;
       the count journal's cost.
credit what credit costs end to end, in one run with the same binaries: env
       steps/s of ./imca train for each task (predator_prey, 4 agents;
       coop_nav with 3 agents) x reward kind (count, rnd, sf) x credit
       (none, shared, imca), with imca / shared, and the share of the
       learner's iteration spent waiting for unrolls (collection, Score and
       pushes: what the learner cannot overlap in synchronous collection);
       then the timeline of each cell: the learner's iteration (waiting,
       training), each actor's unroll by phase (acting, scoring, pushing,
       waiting for the next policy) and the reward server's Score call by
       phase (lock wait, encode, novelty, counterfactual, train, credit).
soak   16 actors for 10 minutes on loopback: RSS of every process every 10 s and
       its growth after warm-up (the count tables' share apart).
drill  kill -9 of the reward server, an actor and the learner 20 s apart in a
       4M-step run, against unbroken runs of the same seed (docs/reliability.md).
learn  the learning benchmark: credit none/shared/independent/imca x 3 seeds
       (--scenario, --reward; further training flags after --); final success
       rate, env steps to 80% and 90%, and imca's credit diagnostics.
       With --variants FILE (a JSON object {"name": {train flag: value}}),
       an ablation: every variant x credit x seed, and a table of medians of
       env steps and wall-clock to 90% success. --out DIR resumes: finished
       runs in DIR are read, not rerun (refused if they ran other settings).
python the Python package against the C++ it wraps, in one run: joint env
       steps/s of imca.make against bench_env at 64, 256 and 1024 envs; Score
       round trips/s and transitions/s of imca.RewardClient against a reward
       server; and examples/python_mappo.py against ./imca train (same PPO
       settings, count IMCA on coop_nav) to 90% success over the last 200
       training episodes, per seed.
"""
import argparse
import csv
import datetime
import importlib.util
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import time

from . import binaries, experiment, options, runs
from .binaries import BIN, ROOT
from .supervisor import run_processes

LAUNCH = binaries.module_argv("train")


# ./imca train's defaults before the learner ablation, and before the concurrent critic.
V1_FLAGS = [word for key, value in runs.V1_DEFAULTS.items()
            for word in (f"--{key.replace('_', '-')}", str(value).lower())] + ["--concurrent-critic", "false"]


def finished_run(out, budget):
    """(summary, rows) of a run folder that reached `budget` uninterrupted, else None."""
    summary = runs.finished_summary(out, budget)
    if summary is None:
        return None
    with open(os.path.join(out, "metrics.csv")) as f:
        return summary, list(csv.DictReader(f))


def train(out, extra):
    if os.path.exists(out):
        shutil.rmtree(out)  # An unfinished run starts over.
    r = subprocess.run(LAUNCH + ["--out", out, "--quiet"] + extra, capture_output=True, text=True,
                       env=binaries.module_env())
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
    # ./imca train's defaults, then those before the learner ablation
    # (docs/benchmarks.md), each against the learner-only ceiling of its shape.
    for name, flags, suffix in [("./imca train defaults", [], ""), ("v1 defaults", V1_FLAGS, "_v1")]:
        print(f"== end-to-end training ({name}{': ' + ' '.join(flags) if flags else ''}) ==", flush=True)
        rates = []
        for i in range(args.repeats):
            _, rows = train(os.path.join(base, f"e2e{suffix}-{i}"), ["--steps", str(args.steps)] + flags)
            rates.append(steady_rate(rows))
            print(f"end_to_end{suffix}_steps_per_sec run {i}: {rates[-1]:.0f}", flush=True)
        e2e = statistics.median(rates)
        learner = float(figures[f"learner{suffix}_steps_per_sec_1thread"])
        print(f"end_to_end{suffix}_steps_per_sec {e2e:.0f}")
        print(f"ratio end_to_end{suffix} / learner{suffix}_only(1 thread) {e2e / learner:.2f}", flush=True)


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


def credit_bench(args, base):
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


def median_reached(values):
    """Median over all seeds with not-reached (None) as infinitely late; None if that is the median."""
    ordered = sorted(float("inf") if v is None else v for v in values)
    if not ordered:
        return None
    m = statistics.median(ordered)
    return None if m == float("inf") else m


def to_90(rows, key):
    """(env steps, wall seconds) at the first row with `key` >= 0.9, or (None, None)."""
    row = runs.first_reaching(rows, 0.9, key)
    return (int(row["env_steps"]), float(row["wall_seconds"])) if row else (None, None)


def ablation_table(args, variants, modes, seeds, results):
    """Medians over seeds; a seed that never got there counts as not reached (k/n)."""
    window = binaries.facts()["success_window"]  # The learner's success window.
    print(f"\n{args.scenario} + {args.reward}, {args.steps:,} env steps, seeds {args.seeds}; success over the "
          f"last {window} training episodes (as marlbenchmark/on-policy) and over the last {window} evaluation episodes")
    print("| variant | credit | env steps to 90%, training episodes: median (per seed) | reached "
          "| wall-clock to 90%: median | env steps to 90%, evaluation: median | final success | env steps/s |")
    print("|---|---|---|---|---|---|---|---|")
    fmt = lambda x: "-" if x is None else f"{x / 1e6:.2f}M"
    for name, _ in variants:
        for credit in modes:
            trials = [results[(name, credit, s)] for s in seeds]
            train = [to_90(rows, "train_success_rate") for _, rows in trials]
            evals = [to_90(rows, "success_rate")[0] for _, rows in trials]
            reached = sum(1 for steps, _ in train if steps is not None)
            wall = median_reached([w for _, w in train])
            print(f"| {name} | {credit} | {fmt(median_reached([x for x, _ in train]))} "
                  f"({' / '.join(fmt(x) for x, _ in train)}) | {reached}/{len(seeds)} "
                  f"| {'-' if wall is None else f'{wall:.1f} s'} | {fmt(median_reached(evals))} "
                  f"| {statistics.mean(s['final_train_success_rate'] for s, _ in trials):.0%} "
                  f"| {statistics.median(s['env_steps_per_sec'] for s, _ in trials):,.0f} |")


def learn(args, base):
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
            conflict = experiment.config_conflict(out, flags + ["--out", out])
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
    steps = lambda xs: " / ".join("-" if x is None else f"{x / 1e6:.2f}M" for x in xs)
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


def rss_bytes(pid):
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def soak(args, base):
    """16 actors (by default) for --minutes on loopback; RSS of every process
    every --every seconds; growth after --warmup minutes, the reward server's
    split into its count tables' (bytes per new distinct key, measured over
    the run) and the rest."""
    run_dir = os.path.join(base, "run")
    launcher = subprocess.Popen(LAUNCH + ["--out", run_dir, "--quiet", "--steps", str(10**12), "--actors",
                                          str(args.actors), "--envs-per-actor", str(args.envs_per_actor),
                                          "--unroll-length", "16", "--batch-steps",
                                          str(args.actors * args.envs_per_actor * 16)] + args.extra,
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=binaries.module_env())
    samples = []  # (seconds, {name: rss}, distinct keys, env steps)
    start = time.time()
    try:
        while time.time() - start < args.minutes * 60:
            time.sleep(args.every)
            if launcher.poll() is not None:
                sys.exit(f"imca bench: the run ended: {launcher.stderr.read().strip()}")
            rss = {name: rss_bytes(pid) for name, pid in run_processes(run_dir).items()}
            status = runs.read_json(os.path.join(run_dir, "logs", "reward_server.status.json")) or {}
            learner = runs.read_json(os.path.join(run_dir, "logs", "learner.status.json")) or {}
            samples.append((time.time() - start, rss, status.get("distinct_keys", 0) + status.get("distinct_local_keys", 0),
                            learner.get("env_steps", 0)))
    finally:
        # SIGTERM, not SIGINT: a shell starting this in the background makes
        # its children ignore SIGINT.
        launcher.send_signal(signal.SIGTERM)
        launcher.wait(timeout=300)
    with open(os.path.join(base, "rss.csv"), "w") as f:
        names = sorted(samples[-1][1])
        f.write("seconds,distinct_keys,env_steps," + ",".join(names) + "\n")
        for t, rss, keys, steps in samples:
            f.write(f"{t:.0f},{keys},{steps}," + ",".join(str(rss.get(n) or "") for n in names) + "\n")
    warm = next(i for i, (t, *_rest) in enumerate(samples) if t >= args.warmup * 60)
    t0, rss0, keys0, steps0 = samples[warm]
    t1, rss1, keys1, steps1 = samples[-1]
    minutes = (t1 - t0) / 60
    print(f"soak: {args.actors} actors x {args.envs_per_actor} envs, {t1 / 60:.1f} min, {steps1:,} env steps "
          f"({(steps1 - steps0) / (t1 - t0):,.0f}/s after warm-up); growth from minute {t0 / 60:.1f} to {t1 / 60:.1f}")
    print("\n| process | RSS at warm-up (MB) | RSS at end (MB) | growth (MB) | growth (MB/min) |")
    print("|---|---|---|---|---|")
    for name in sorted(rss1, key=lambda n: (not n.startswith("reward"), not n.startswith("learner"), n)):
        if rss0.get(name) is None or rss1.get(name) is None:
            continue
        growth = (rss1[name] - rss0[name]) / 1e6
        print(f"| {name} | {rss0[name] / 1e6:.1f} | {rss1[name] / 1e6:.1f} | {growth:+.1f} | {growth / minutes:+.2f} |")
    # The count tables' legitimate growth: bytes per distinct key from the
    # whole run (first to last sample), applied to the keys added after warm-up.
    first_t, first_rss, first_keys, _ = samples[0]
    if "reward_server" in rss1 and keys1 > first_keys:
        per_key = (rss1["reward_server"] - first_rss["reward_server"]) / (keys1 - first_keys)
        tables = per_key * (keys1 - keys0) / 1e6
        growth = (rss1["reward_server"] - rss0["reward_server"]) / 1e6
        print(f"\nreward server: {keys1 - keys0:,} new distinct keys after warm-up ({keys1:,} in all), "
              f"{per_key:.0f} bytes per key over the run: tables {tables:+.1f} MB of its {growth:+.1f} MB, "
              f"other {growth - tables:+.1f} MB")
    print(f"\nsamples: {os.path.join(base, 'rss.csv')}")


def drill(args, base):
    """The acceptance drill by hand: one run of --steps with kill -9 of the
    reward server, then actor-1, then the learner, --gap seconds apart
    (from --first s in), against --unbroken runs of the same seed."""
    flags = ["--steps", str(args.steps), "--seed", str(args.seed)] + args.extra
    results = []
    for k in range(args.unbroken):
        summary, _ = train(os.path.join(base, f"unbroken-{k + 1}"), flags)
        results.append(("unbroken", summary, []))
        print(f"unbroken {k + 1}: final success {summary['final_success_rate']:.1%}, "
              f"{summary['env_steps']:,} env steps in {summary['wall_seconds']:.0f} s", flush=True)
    run_dir = os.path.join(base, "killed")
    if os.path.exists(run_dir):
        shutil.rmtree(run_dir)
    launcher = subprocess.Popen(LAUNCH + ["--out", run_dir, "--quiet"] + flags, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, text=True, env=binaries.module_env())
    kills = []
    logs = os.path.join(run_dir, "logs")
    start = time.time()
    for k, victim in enumerate(["reward_server", "actor-1", "learner"]):
        while time.time() - start < args.first + k * args.gap:
            time.sleep(0.1)
        pid = run_processes(run_dir).get(victim)
        if pid is None:
            sys.exit(f"imca bench: no {victim} to kill (the run ended?)")
        # What the victim had said just before (its status is at most 1 s old).
        before = runs.read_json(os.path.join(logs, f"{victim}.status.json")) or {}
        learner = runs.read_json(os.path.join(logs, "learner.status.json")) or {}
        os.kill(pid, signal.SIGKILL)
        kills.append((victim, time.time() - start, before, learner))
        print(f"killed {victim} at {time.time() - start:.0f} s ({learner.get('env_steps', 0):,} env steps)", flush=True)
    _, err = launcher.communicate()
    if launcher.returncode != 0:
        sys.exit(f"imca bench: the killed run failed: {err.strip()}")
    summary = runs.read_json(os.path.join(run_dir, "summary.json"))
    reward = runs.read_json(os.path.join(run_dir, "logs", "reward_server.status.json"))
    learner = runs.read_json(os.path.join(run_dir, "logs", "learner.status.json"))
    answered = sum((runs.read_json(os.path.join(run_dir, "logs", f"actor-{i}.status.json")) or {})
                   .get("transitions_scored", 0) for i in range(2))
    unbroken = [r[1]["final_success_rate"] for r in results]
    print("\n| run | final success | env steps | wall s | restarts |")
    print("|---|---|---|---|---|")
    for k, (_, s_, _) in enumerate(results):
        print(f"| unbroken {k + 1} | {s_['final_success_rate']:.1%} | {s_['env_steps']:,} | {s_['wall_seconds']:.0f} | 0 |")
    print(f"| killed | {summary['final_success_rate']:.1%} | {summary['env_steps']:,} | {summary['wall_seconds']:.0f} | "
          f"{', '.join(f'{n} {c}' for n, c in summary['restarts'].items() if c)} |")
    if unbroken:
        print(f"\nunbroken spread {min(unbroken):.1%}-{max(unbroken):.1%}; killed run "
              f"{'inside' if min(unbroken) <= summary['final_success_rate'] <= max(unbroken) else 'outside'} it")
    # What each kill lost, from the logs and status files.
    def log_text(name):
        try:
            with open(os.path.join(logs, name)) as f:
                return f.read()
        except OSError:
            return ""
    for victim, at, before, learner_then in kills:
        if victim == "reward_server":
            text = log_text("reward_server.1.log")
            restored = int(text.split("(")[1].split()[0]) if "restored from" in text else 0
            print(f"reward server killed at {at:.0f} s: it had counted {before.get('transitions_scored', 0):,} "
                  f"transitions (status, <= 1 s old); restarted with {restored:,} restored")
        elif victim == "actor-1":
            trained = [r for r in runs.read_metrics(os.path.join(logs, "trained_unrolls.csv"))
                       if r["actor_id"] == "actor-1" and r["incarnation"] == f"{before.get('incarnation', 0):016x}"]
            print(f"actor-1 killed at {at:.0f} s: its incarnation {before.get('incarnation', 0):016x} had "
                  f"{before.get('unrolls_pushed', 0)} unrolls acked (status, <= 1 s old), {len(trained)} trained "
                  f"and kept; resent across all kills: "
                  f"{sum((runs.read_json(os.path.join(logs, f'actor-{i}.status.json')) or {}).get('unrolls_resent', 0) for i in range(2))}"
                  " (surviving incarnations)")
        else:
            text = log_text("learner.1.log")
            resumed = int(text.split("resumed at policy version ")[1].split()[0]) if "resumed at" in text else 0
            print(f"learner killed at {at:.0f} s at policy version {learner_then.get('policy_version', 0)} "
                  f"({learner_then.get('env_steps', 0):,} env steps); resumed at version {resumed}: "
                  f"{learner_then.get('policy_version', 0) - resumed} iterations of training redone")
    print(f"learner after its restart: duplicates dropped {learner['unrolls_duplicate']}, "
          f"actor incarnations {learner['actor_incarnations']}; reward server transitions_scored "
          f"{reward['transitions_scored']:,} (the surviving actors' answered Scores alone: {answered:,})")
    print(f"run folders: {base}")


def median_rate(work, count, rounds):
    """Median of count / seconds over `rounds` timed calls of work()."""
    rates = []
    for _ in range(rounds):
        start = time.perf_counter()
        work()
        rates.append(count / (time.perf_counter() - start))
    return statistics.median(rates)


def start_reward_server(base, scenario):
    """(process, address) of a count/imca reward server on a free loopback port."""
    port_file = os.path.join(base, "reward_server.port")
    log = open(os.path.join(base, "reward_server.log"), "w")
    proc = subprocess.Popen([os.path.join(BIN, "reward_server"), f"--scenario={scenario}", "--reward=count",
                             "--credit=imca", "--listen=127.0.0.1:0", f"--port_file={port_file}"],
                            stdout=log, stderr=subprocess.STDOUT)
    deadline = time.time() + 30
    while not (os.path.exists(port_file) and open(port_file).read().strip()):
        if proc.poll() is not None or time.time() > deadline:
            sys.exit(f"imca bench: the reward server did not start (log: {log.name})")
        time.sleep(0.05)
    return proc, f"127.0.0.1:{open(port_file).read().strip()}"


def python_bench(args, base):
    # The package comes from PYTHONPATH (./imca bench puts python/ there).
    if importlib.util.find_spec("imca") is None:
        sys.exit("imca bench python: the Python package (python/imca) is not importable; "
                 "run it as ./imca bench python (which sets PYTHONPATH)")
    parts = args.parts.split(",")
    unknown = set(parts) - {"env", "score", "train"}
    if unknown:
        sys.exit(f"imca bench python: --parts: unknown part(s) {', '.join(sorted(unknown))} (env, score, train)")
    sizes = [int(x) for x in args.envs.split(",")]
    if "env" in parts:
        python_env_bench(args, sizes)
    if "score" in parts:
        python_score_bench(args, base)
    if "train" in parts:
        python_train_bench(args, base)


def python_env_bench(args, sizes):
    import numpy as np
    import imca
    print(f"== joint env steps/s, one core: imca.make from Python against bench_env (C++), medians of "
          f"{args.rounds} rounds of 2000 steps; uniform random actions drawn beforehand ==", flush=True)
    r = subprocess.run([os.path.join(BIN, "bench_env"), str(args.rounds)] + [str(e) for e in sizes],
                       capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"imca bench: bench_env failed: {r.stderr.strip()}")
    # Python's step featurises too: compare with C++'s step + featurise.
    cxx = {(w[0], int(w[2])): (float(w[3]), float(w[5]))
           for w in (line.split() for line in r.stdout.splitlines()[1:])}
    print("| scenario | agents | envs | C++ step | C++ step + featurise | Python step (+ featurise) "
          "| Python / C++ (same work) |")
    print("|---|---|---|---|---|---|---|")
    for scenario in imca.scenarios():
        for E in sizes:
            env = imca.make(scenario, num_envs=E, seed=1)
            env.reset()
            pool = np.random.default_rng(5).integers(0, env.num_actions, (64, E, env.num_agents), dtype=np.int32)
            def steps(env=env, pool=pool):
                for t in range(2000):
                    env.step(pool[t % 64])
            rate = median_rate(steps, 2000 * E, args.rounds)
            bare, featurised = cxx[(scenario, E)]
            print(f"| {scenario} | {env.num_agents} | {E} | {bare:,.0f} | {featurised:,.0f} | {rate:,.0f} "
                  f"| {rate / featurised:.2f} |", flush=True)


def python_score_bench(args, base):
    import numpy as np
    import imca
    print(f"\n== Score from Python: imca.RewardClient against reward_server (coop_nav, count, imca) on "
          f"loopback; medians of {args.rounds} rounds ==", flush=True)
    r = subprocess.run([os.path.join(BIN, "bench_reward"), str(args.rounds), "count", "coop_nav"],
                       capture_output=True, text=True, env=dict(os.environ, OMP_WAIT_POLICY="passive"))
    if r.returncode != 0:
        sys.exit(f"imca bench: bench_reward failed: {r.stderr.strip()}")
    cxx = float(r.stdout.splitlines()[1].split()[3])
    server, address = start_reward_server(base, "coop_nav")
    try:
        client = imca.RewardClient(address, actor_id="bench-python")
        print("| client | steps x envs per call | round trips/s | transitions/s |")
        print("|---|---|---|---|")
        print(f"| C++ (bench_reward, server in its process) | 64 x 32 | {cxx / 2048:,.0f} | {cxx:,.0f} |")
        for T, E in ((1, 1), (32, 64), (64, 32)):
            env = imca.make("coop_nav", num_envs=E, seed=2)
            obs, info = env.reset()
            rng = np.random.default_rng(3)
            states, actions = [info["state"]], []
            for t in range(T):
                actions.append(rng.integers(0, env.num_actions, (E, env.num_agents)))
                states.append(env.step(actions[-1])[4]["state"])
            states, actions = np.stack(states), np.stack(actions)
            probs = np.full(actions.shape + (env.num_actions,), 1 / env.num_actions, np.float32)
            calls = max(5, min(2000, 20000 // (T * E)))
            def score():
                for _ in range(calls):
                    client.score(states, actions, probs, env=env)
            rate = median_rate(score, calls, args.rounds)
            print(f"| Python (imca.RewardClient) | {T} x {E} | {rate:,.0f} | {rate * T * E:,.0f} |", flush=True)
        client.close()
    finally:
        server.terminate()
        server.wait()


def python_train_bench(args, base):
    seeds = [int(s) for s in args.seeds.split(",")]
    print(f"\n== coop_nav, count IMCA, to 90% success over the last 200 training episodes "
          f"(budget {args.steps:,} env steps; seeds {args.seeds}) ==", flush=True)
    results = {"python_mappo": [], "./imca train": []}
    for seed in seeds:
        log_path = os.path.join(base, f"python_mappo-seed{seed}.log")
        with open(log_path, "w") as log:
            p = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "python_mappo.py"), "--seed", str(seed),
                                "--steps", str(args.steps)], stdout=log, stderr=subprocess.STDOUT)
        lines = open(log_path).read().splitlines()
        if p.returncode != 0:
            sys.exit(f"imca bench: python_mappo failed (log: {log_path})")
        reached = [l.split() for l in lines if l.startswith("reached ")]
        last = [l.split() for l in lines if l.startswith("iteration ")][-1]
        rate = float(last[last.index("steps/s") + 1])
        steps90, wall90 = (int(reached[0][4]), float(reached[0][7])) if reached else (None, None)
        results["python_mappo"].append((steps90, wall90, rate))
        print(f"python_mappo  seed {seed}: to 90% {steps90} env steps / {wall90} s, {rate:,.0f} env steps/s",
              flush=True)
        # ./imca train runs its whole budget; the rows say when 90% was reached.
        summary, rows = train(os.path.join(base, f"imca_train-seed{seed}"),
                              ["--seed", str(seed), "--steps", str(args.steps)])
        steps90, wall90 = to_90(rows, "train_success_rate")
        rate = int(rows[-1]["env_steps"]) / float(rows[-1]["wall_seconds"])
        results["./imca train"].append((steps90, wall90, rate))
        print(f"./imca train seed {seed}: to 90% {steps90} env steps / {wall90} s, {rate:,.0f} env steps/s",
              flush=True)
    fmt = lambda x: "-" if x is None else f"{x / 1e6:.2f}M"
    print("| trainer | env steps to 90%: median (per seed) | reached | wall-clock to 90%: median (per seed) "
          "| env steps/s: median |")
    print("|---|---|---|---|---|")
    for name, trials in results.items():
        wall = median_reached([w for _, w, _ in trials])
        print(f"| {name} | {fmt(median_reached([s for s, _, _ in trials]))} ({' / '.join(fmt(s) for s, _, _ in trials)}) "
              f"| {sum(s is not None for s, _, _ in trials)}/{len(trials)} "
              f"| {'-' if wall is None else f'{wall:.1f} s'} "
              f"({' / '.join('-' if w is None else f'{w:.0f} s' for _, w, _ in trials)}) "
              f"| {statistics.median(r for _, _, r in trials):,.0f} |")
    print(f"run folders and logs: {base}")


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
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
    cr = sub.add_parser("credit")
    cr.add_argument("--steps", type=int, default=400_000, help="env steps of each run")
    cr.add_argument("--rewards", default="count,rnd,sf")
    cr.add_argument("--credits", default="none,shared,imca")
    cr.add_argument("--seed", type=int, default=1)
    cr.add_argument("--repeats", type=int, default=1, help="runs of each cell, interleaved; the median is reported")
    cr.add_argument("extra", nargs="*",
                    help="after --: more ./imca train flags for every cell, e.g. -- --reward-threads 2")
    sk = sub.add_parser("soak")
    sk.add_argument("--actors", type=int, default=16)
    sk.add_argument("--envs-per-actor", type=int, default=8)
    sk.add_argument("--minutes", type=float, default=10)
    sk.add_argument("--warmup", type=float, default=2, help="minutes before growth is measured")
    sk.add_argument("--every", type=float, default=10, help="seconds between RSS samples")
    sk.add_argument("extra", nargs="*", help="after --: more ./imca train flags")
    dr = sub.add_parser("drill")
    dr.add_argument("--steps", type=int, default=4_000_000)
    dr.add_argument("--seed", type=int, default=1)
    dr.add_argument("--unbroken", type=int, default=3, help="runs of the same seed without kills")
    dr.add_argument("--first", type=float, default=20, help="seconds into the run of the first kill")
    dr.add_argument("--gap", type=float, default=20, help="seconds between kills")
    dr.add_argument("extra", nargs="*", help="after --: more ./imca train flags")
    l = sub.add_parser("learn")
    l.add_argument("--credits", default="none,shared,independent,imca")
    l.add_argument("--seeds", default="1,2,3")
    l.add_argument("--steps", type=int, default=2_000_000)
    l.add_argument("--scenario", default="coop_nav")
    l.add_argument("--reward", default="count")
    l.add_argument("--variants", default="", help="JSON file {name: {train flag: value}}: an ablation")
    l.add_argument("--out", default="", help="run folder (reruns skip its finished runs)")
    l.add_argument("extra", nargs="*", help="after --: more ./imca train flags, e.g. -- --beta 0.1")
    py = sub.add_parser("python")
    py.add_argument("--rounds", type=int, default=7)
    py.add_argument("--parts", default="env,score,train", help="which comparisons (env, score, train)")
    py.add_argument("--envs", default="64,256,1024", help="env counts of the env comparison")
    py.add_argument("--seeds", default="1,2,3")
    py.add_argument("--steps", type=int, default=2_000_000, help="training budget in env steps")
    args = p.parse_args(options.dashed(argv))
    if args.what not in ("learn", "soak", "drill", "credit"):
        args.extra = []
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    base = getattr(args, "out", "") or os.path.join(ROOT, "runs", f"bench-{args.what}-"
                        + (f"{args.scenario}-{args.reward}-" if args.what == "learn" else "") + stamp)
    base = os.path.abspath(base)
    os.makedirs(base, exist_ok=True)
    {"speed": speed, "env": env_bench, "reward": reward_bench, "credit": credit_bench, "learn": learn, "soak": soak,
     "drill": drill, "python": python_bench}[args.what](args, base)


if __name__ == "__main__":
    main()
