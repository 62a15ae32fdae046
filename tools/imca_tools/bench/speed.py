"""./imca bench speed: component ceilings (bench_speed) and end-to-end training
throughput, with the ratio end-to-end / learner-only."""
import os
import statistics

from .. import runs
from .common import run_binary, steady_rate, train

# ./imca train's defaults before the learner ablation, before the concurrent
# critic and before edition v4's collection (32 envs per actor; its 16 eval
# envs per actor are now 8, which ./imca train does not set).
V1_FLAGS = [word for key, value in runs.V1_DEFAULTS.items()
            for word in (f"--{key.replace('_', '-')}", str(value).lower())] + ["--concurrent-critic", "false",
                                                                               "--envs-per-actor", "32"]


def run(args, base):
    print("== component ceilings (medians of timed rounds) ==", flush=True)
    r = run_binary("bench_speed", args.rounds)
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
