"""./imca bench reward: Score throughput for count, rnd, sf with 2 and 4 agents;
counterfactual share; the count journal's cost."""
from .common import exit_if_failed, run_binary


def run(args, base):
    r = run_binary("bench_reward", args.rounds)
    print(r.stdout, end="")
    exit_if_failed(r, "bench_reward")
