#!/usr/bin/python3
"""--deterministic against the real binaries: two short runs of ./imca train
(2 actors, count imca) whose actors' calls arrive in opposite orders write
the same files byte for byte (imca_tools.same_run); without the flag, the
same two runs differ, which shows the arrival orders really were opposite."""
import contextlib
import io
import json
import os
import subprocess
import tempfile
import unittest

from imca_tools import binaries, same_run

LAUNCH = binaries.module_argv("train")
# 16 iterations of 1,024 joint steps, two actors of 8 envs x 32 steps: each
# actor sends two unrolls per policy version.
SHORT = ["--actors", "2", "--envs-per-actor", "8", "--unroll-length", "32", "--batch-steps", "1024",
         "--steps", "16384", "--quiet"]


def train(out, delays, *flags, env=None):
    # Actor 0 pauses before each Score call in one run, actor 1 in the other:
    # their calls reach the reward server and the learner in opposite orders.
    r = subprocess.run(LAUNCH + SHORT + ["--out", out, "--actor-score-delays-ms", delays, *flags],
                       capture_output=True, text=True, timeout=300, env=env)
    if r.returncode != 0:
        raise AssertionError(f"imca train failed ({r.returncode}): {r.stderr[-2000:]}")


class DeterministicRunTest(unittest.TestCase):
    def check_pair(self, *flags, deterministic=True):
        with tempfile.TemporaryDirectory() as tmp:
            a, b = os.path.join(tmp, "a"), os.path.join(tmp, "b")
            train(a, "40,0", "--deterministic", str(deterministic).lower(), *flags)
            train(b, "0,40", "--deterministic", str(deterministic).lower(), *flags)
            rows, same = same_run.differences(a, b)
            names = {name for name, _, _ in rows}
            for wanted in ("policy.pb", "reward_snapshot.bin (no journal line)", "metrics.csv (no wall columns)"):
                self.assertIn(wanted, names)
            self.assertTrue(any(n.startswith("checkpoints/") and n.endswith(".pt") for n in names), names)
            return rows, same

    def test_count_imca_runs_are_identical_whatever_the_arrival_order(self):
        rows, same = self.check_pair()
        self.assertTrue(same, "\n".join(f"{n}: {x} {y}" for n, x, y in rows if x != y))

    def test_rnd_runs_are_identical_whatever_the_arrival_order(self):
        rows, same = self.check_pair("--reward", "rnd")
        self.assertTrue(same, "\n".join(f"{n}: {x} {y}" for n, x, y in rows if x != y))

    def test_synchronous_maddpg_runs_are_identical_whatever_the_arrival_order(self):
        rows, same = self.check_pair("--algo", "maddpg", "--sync", "true", "--steps", "30720")
        self.assertTrue(same, "\n".join(f"{n}: {x} {y}" for n, x, y in rows if x != y))

    def test_without_the_flag_the_arrival_order_shows(self):
        # The control: if these were equal, the delays did not reorder the
        # calls and the tests above would prove nothing.
        rows, same = self.check_pair(deterministic=False)
        different = {n for n, x, y in rows if x != y}
        self.assertIn("metrics.csv (no wall columns)", different)
        self.assertIn("reward_snapshot.bin (no journal line)", different)

    def test_runs_name_their_cpu_kernels_and_builds_and_same_run_says_when_they_differ(self):
        # OpenBLAS's kernels and ATen's level are conditions of a replay
        # (docs/learner.md): each run records the ones its servers ran, and
        # same_run says when two runs ran other ones. Prescott's and
        # Haswell's kernels run on every CPU these binaries run on.
        with tempfile.TemporaryDirectory() as tmp:
            ran = {}
            for name, core, level in (("old", "Prescott", "default"), ("new", "Haswell", "avx2")):
                out = os.path.join(tmp, name)
                train(out, "0,0", "--deterministic", "true", "--reward", "rnd",
                      env=dict(os.environ, OPENBLAS_CORETYPE=core, ATEN_CPU_CAPABILITY=level))
                with open(os.path.join(out, "summary.json")) as f:
                    ran[name] = json.load(f)["kernels"]
                expected = f"aten={level} openblas={core}"
                self.assertEqual(ran[name], {"learner": expected, "reward_server": expected})
            printed = io.StringIO()
            with contextlib.redirect_stdout(printed):
                same_run.main([os.path.join(tmp, "old"), os.path.join(tmp, "new")])
            self.assertIn(f"other CPU kernels ({ran['old']} against {ran['new']})", printed.getvalue())
            # Both ran this build, each from its own copy (config.json's sha256 per binary).
            self.assertNotIn("other builds", printed.getvalue())
            # A learner of another build (as if rebuilt between the runs): said, by name.
            config_path = os.path.join(tmp, "new", "config.json")
            with open(config_path) as f:
                config = json.load(f)
            self.assertEqual(set(config["binaries"]), {"reward_server", "learner", "actor", "imca_env"})
            config["binaries"]["learner"] = "0" * 64
            with open(config_path, "w") as f:
                json.dump(config, f)
            printed = io.StringIO()
            with contextlib.redirect_stdout(printed):
                same_run.main([os.path.join(tmp, "old"), os.path.join(tmp, "new")])
            self.assertIn("the runs ran other builds of learner (config.json's binaries)", printed.getvalue())

    def test_deterministic_needs_synchronous_collection(self):
        with tempfile.TemporaryDirectory() as tmp:
            r = subprocess.run(LAUNCH + SHORT + ["--out", os.path.join(tmp, "a"), "--deterministic", "true",
                                                 "--sync", "false"], capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertIn("--deterministic", r.stderr)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)


if __name__ == "__main__":
    unittest.main()
