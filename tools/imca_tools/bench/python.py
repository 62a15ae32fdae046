"""./imca bench python: the Python package against the C++ it wraps, in one run:
imca.make against bench_env, imca.RewardClient against a reward server, and
examples/python_mappo.py against ./imca train."""
import importlib.util
import os
import statistics
import subprocess
import sys
import time

from ..binaries import BIN, ROOT
from .common import exit_if_failed, median_reached, millions, run_binary, to_90, train


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


def run(args, base):
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
    # numpy and the Python package are imported here, not at the top of this
    # module: run() first says in one line when the package is not importable,
    # and --parts train needs neither.
    import numpy as np
    import imca
    print(f"== joint env steps/s, one core: imca.make from Python against bench_env (C++), medians of "
          f"{args.rounds} rounds of 2000 steps; uniform random actions drawn beforehand ==", flush=True)
    r = run_binary("bench_env", args.rounds, *sizes)
    exit_if_failed(r, "bench_env")
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
    import numpy as np  # Here, not at the top: see python_env_bench.
    import imca
    print(f"\n== Score from Python: imca.RewardClient against reward_server (coop_nav, count, imca) on "
          f"loopback; medians of {args.rounds} rounds ==", flush=True)
    r = run_binary("bench_reward", args.rounds, "count", "coop_nav")
    exit_if_failed(r, "bench_reward")
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
    print("| trainer | env steps to 90%: median (per seed) | reached | wall-clock to 90%: median (per seed) "
          "| env steps/s: median |")
    print("|---|---|---|---|---|")
    for name, trials in results.items():
        wall = median_reached([w for _, w, _ in trials])
        print(f"| {name} | {millions(median_reached([s for s, _, _ in trials]))} "
              f"({' / '.join(millions(s) for s, _, _ in trials)}) "
              f"| {sum(s is not None for s, _, _ in trials)}/{len(trials)} "
              f"| {'-' if wall is None else f'{wall:.1f} s'} "
              f"({' / '.join('-' if w is None else f'{w:.0f} s' for _, w, _ in trials)}) "
              f"| {statistics.median(r for _, _, r in trials):,.0f} |")
    print(f"run folders and logs: {base}")
