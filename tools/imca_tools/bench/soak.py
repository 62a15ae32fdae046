"""./imca bench soak: 16 actors (by default) for 10 minutes on loopback: RSS of
every process every 10 s and its growth after warm-up (the count tables' share apart)."""
import os
import signal
import subprocess
import sys
import time

from .. import binaries, runs
from ..supervisor import run_processes
from .common import LAUNCH


def rss_bytes(pid):
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def run(args, base):
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
