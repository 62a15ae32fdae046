"""./imca bench env: joint env steps/s of every scenario on one core (vectorised)."""
from .common import exit_if_failed, run_binary


def run(args, base):
    r = run_binary("bench_env", args.rounds)
    print(r.stdout, end="")
    exit_if_failed(r, "bench_env")
