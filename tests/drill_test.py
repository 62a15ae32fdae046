#!/usr/bin/python3
"""Kill-and-count drills: ./imca train survives the death of any of its processes.

Each drill starts a real run through ./imca train (imca_tools.train), kills one process with
SIGKILL (or stops it with SIGSTOP, for the stall detector) mid-run, lets the
run reach its budget, and then counts: the run exits 0, the restart is
counted, and what each role promises (docs/reliability.md) holds.
"""
import csv
import json
import os
import signal
import subprocess
import tempfile
import time
import unittest

from imca_tools import binaries
from imca_tools.supervisor import run_processes  # a run's live processes by name

ROOT = os.environ.get("IMCA_ROOT", os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
LAUNCH = binaries.module_argv("train")
SMALL = ["--actors", "2", "--envs-per-actor", "8", "--unroll-length", "32", "--batch-steps", "1024", "--quiet",
         "--checkpoint-seconds", "1", "--snapshot-every", "2"]
BUDGET = 400_000


def read_json(path):
    with open(path) as f:
        return json.load(f)


def rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


class Drill:
    """One run of ./imca train that the test disturbs."""

    def __init__(self, out, extra=()):
        self.run_dir = os.path.join(out, "run")
        self.proc = subprocess.Popen(LAUNCH + ["--steps", str(BUDGET), "--out", self.run_dir] + SMALL + list(extra),
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def wait_for_iterations(self, count, timeout=120):
        deadline = time.time() + timeout
        path = os.path.join(self.run_dir, "metrics.csv")
        while time.time() < deadline:
            if os.path.exists(path) and len(rows(path)) >= count:
                return
            if self.proc.poll() is not None:
                raise AssertionError(f"run ended early: {self.proc.stderr.read()}")
            time.sleep(0.1)
        raise AssertionError("no progress")

    def signal(self, name, sig):
        pid = run_processes(self.run_dir).get(name)
        assert pid is not None, f"no {name} running"
        os.kill(pid, sig)
        return pid

    def finish(self, timeout=180):
        out, err = self.proc.communicate(timeout=timeout)
        self.stderr = err
        self.summary = read_json(os.path.join(self.run_dir, "summary.json"))
        self.logs = os.path.join(self.run_dir, "logs")
        return self.proc.returncode

    def status(self, name):
        return read_json(os.path.join(self.logs, name + ".status.json"))

    def trained(self):
        return rows(os.path.join(self.logs, "trained_unrolls.csv"))


class DrillTest(unittest.TestCase):
    def finished_with_one_restart(self, drill, name):
        code = drill.finish()
        self.assertEqual(code, 0, drill.stderr)
        self.assertGreaterEqual(drill.summary["env_steps"], BUDGET)
        self.assertFalse(drill.summary["interrupted"])
        self.assertEqual(drill.summary["restarts"][name], 1, drill.summary["restarts"])
        self.assertEqual(sum(drill.summary["restarts"].values()), 1, drill.summary["restarts"])
        self.assertIn(name, drill.stderr)
        with open(os.path.join(drill.logs, "restarts.csv")) as f:
            self.assertIn(name, f.read())
        self.assertTrue(os.path.exists(os.path.join(drill.logs, name + ".1.log")))
        # Never trained twice: each (actor, incarnation, sequence) once.
        keys = [(r["actor_id"], r["incarnation"], r["sequence"]) for r in drill.trained()]
        self.assertEqual(len(keys), len(set(keys)))
        # Iterations and env steps only go forward in metrics.csv.
        metrics = rows(os.path.join(drill.run_dir, "metrics.csv"))
        iterations = [int(r["iteration"]) for r in metrics]
        steps = [int(r["env_steps"]) for r in metrics]
        self.assertEqual(iterations, sorted(set(iterations)))
        self.assertEqual(steps, sorted(steps))

    def test_reward_server_killed(self):
        with tempfile.TemporaryDirectory() as out:
            drill = Drill(out)
            drill.wait_for_iterations(20)
            drill.signal("reward_server", signal.SIGKILL)
            self.finished_with_one_restart(drill, "reward_server")
            # Every Score an actor had answered is in the restarted server's
            # counts (journal): at least all of them, and at most one retried
            # unroll per actor more (an answer lost with the dead process).
            answered = sum(drill.status(f"actor-{i}")["transitions_scored"] for i in range(2))
            served = drill.status("reward_server")["transitions_scored"]
            self.assertGreaterEqual(served, answered)
            self.assertLessEqual(served, answered + 2 * 8 * 32)
            self.assertGreater(drill.status("reward_server")["distinct_keys"], 0)
            with open(os.path.join(drill.logs, "reward_server.1.log")) as f:
                self.assertIn("restored from", f.read())

    def test_actor_killed(self):
        with tempfile.TemporaryDirectory() as out:
            drill = Drill(out)
            drill.wait_for_iterations(20)
            drill.signal("actor-1", signal.SIGKILL)
            self.finished_with_one_restart(drill, "actor-1")
            # The new incarnation trained, under its own id, and the dead one's
            # data stopped where it died.
            incarnations = {r["incarnation"] for r in drill.trained() if r["actor_id"] == "actor-1"}
            self.assertEqual(len(incarnations), 2)
            self.assertIn(f'{drill.status("actor-1")["incarnation"]:016x}', incarnations)
            self.assertEqual(drill.status("learner")["actor_incarnations"], 3)

    def test_learner_killed(self):
        with tempfile.TemporaryDirectory() as out:
            # Checkpoints every 50 iterations only: the restarted learner goes
            # back ~20 versions, and the actors' unrolls in hand are ahead of it.
            drill = Drill(out, ["--checkpoint-seconds", "0"])
            drill.wait_for_iterations(70)
            checkpoints = os.path.join(drill.run_dir, "checkpoints")
            newest = max(f for f in os.listdir(checkpoints) if f.endswith(".meta"))
            drill.signal("learner", signal.SIGKILL)
            self.finished_with_one_restart(drill, "learner")
            # The restarted learner went on from a checkpoint at least as new
            # as the newest one before the kill.
            with open(os.path.join(drill.logs, "learner.1.log")) as f:
                log = f.read()
            self.assertIn("resumed at policy version", log)
            resumed = int(log.split("resumed at policy version ")[1].split()[0])
            self.assertGreaterEqual(resumed, int(newest.split("-")[1].split(".")[0]))

    def test_stalled_actor_is_restarted(self):
        # Alive but silent (SIGSTOP): its status file goes quiet, and the
        # supervisor kills and restarts it; the other actor, waiting for the
        # policy the stopped one holds up, is not touched.
        with tempfile.TemporaryDirectory() as out:
            drill = Drill(out, ["--stall-seconds", "10"])
            drill.wait_for_iterations(10)
            pid = drill.signal("actor-0", signal.SIGSTOP)
            try:
                self.finished_with_one_restart(drill, "actor-0")
            finally:
                try:
                    os.kill(pid, signal.SIGKILL)
                except OSError:
                    pass
            with open(os.path.join(drill.logs, "restarts.csv")) as f:
                self.assertIn("made no progress", f.read())


if __name__ == "__main__":
    unittest.main(verbosity=2)
