"""./imca bench drill: kill -9 of the reward server, an actor and the learner in
one run, against unbroken runs of the same seed (docs/reliability.md)."""
import os
import shutil
import signal
import subprocess
import sys
import time

from .. import binaries, runs
from ..supervisor import run_processes
from .common import LAUNCH, train


def run(args, base):
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
