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
import datetime
import os
import sys

from .. import options
from ..binaries import ROOT
from . import credit, drill, env, learn, python, reward, soak, speed

# Each part's module, by sub-command; its run(args, base) runs it.
PARTS = {"speed": speed, "env": env, "reward": reward, "credit": credit, "learn": learn, "soak": soak,
         "drill": drill, "python": python}


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
    PARTS[args.what].run(args, base)


if __name__ == "__main__":
    main()
