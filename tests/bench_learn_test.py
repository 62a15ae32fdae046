#!/usr/bin/python3
"""./imca bench learn (imca_tools.bench) against the real binaries: a tiny
learning benchmark runs, resumes from its --out, and refuses to mix in
finished runs of other settings."""
import json
import os
import subprocess
import tempfile
import unittest

from imca_tools import binaries

BENCH = binaries.module_argv("bench", "learn")
# One credit mode, one seed, a few iterations of coop_nav.
SMALL = ["--credits", "shared", "--seeds", "1", "--steps", "16000", "--scenario", "coop_nav", "--reward", "count"]
TRAIN = ["--", "--actors", "1", "--envs-per-actor", "8", "--unroll-length", "32", "--batch-steps", "1024"]


def bench(*argv, timeout=300):
    return subprocess.run(BENCH + list(argv), capture_output=True, text=True, timeout=timeout,
                          env=binaries.module_env())


class BenchLearnTest(unittest.TestCase):
    def test_resumes_its_out_and_refuses_runs_of_other_settings(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "out")
            r = bench("--out", out, *SMALL, *TRAIN)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertIn("default      shared       seed 1: final success", r.stdout)
            self.assertIn("| shared |", r.stdout)
            summary = os.path.join(out, "shared-seed1", "summary.json")
            first = os.stat(summary).st_mtime_ns

            # The same command reads the finished run instead of training it again.
            r = bench("--out", out, *SMALL, *TRAIN, timeout=120)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertIn("| shared |", r.stdout)
            self.assertEqual(os.stat(summary).st_mtime_ns, first)

            # Another learning rate: the finished run is not this benchmark's.
            r = bench("--out", out, *SMALL, *TRAIN, "--lr", "0.0123", timeout=120)
            self.assertEqual(r.returncode, 1, r.stderr)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertIn(f"{os.path.join(out, 'shared-seed1')} was run with lr", r.stderr)
            self.assertIn("where ./imca train now uses 0.0123", r.stderr)
            self.assertIn("another --out", r.stderr)
            self.assertEqual(os.stat(summary).st_mtime_ns, first, "the finished run must be left as it was")

            # A flag ./imca train does not take is its one-line message.
            r = bench("--out", out, *SMALL, *TRAIN, "--lrr", "0.1", timeout=120)
            self.assertEqual(r.returncode, 1, r.stderr)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertIn("--lrr", r.stderr)


    def test_an_ablation_compares_every_variant_with_the_first(self):
        with tempfile.TemporaryDirectory() as tmp:
            variants = os.path.join(tmp, "variants.json")
            with open(variants, "w") as f:
                json.dump({"base": {}, "faster": {"lr": 0.002}}, f)
            r = bench("--out", os.path.join(tmp, "out"), "--variants", variants, *SMALL, *TRAIN)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertIn("P(sooner) against base", r.stdout)
            header = next(line for line in r.stdout.splitlines() if line.startswith("| variant |"))
            columns = [c.strip() for c in header.strip("|").split("|")]
            self.assertEqual(columns[3:5], ["IQM", "P(sooner)"])
            self.assertEqual(columns[-1], "arm wall-clock")
            rows = {line.split("|")[1].strip(): [c.strip() for c in line.strip("|").split("|")]
                    for line in r.stdout.splitlines() if line.startswith(("| base |", "| faster |"))}
            self.assertEqual(set(rows), {"base", "faster"})
            # 16k steps never reach 90%: both are censored at the budget, a tie.
            self.assertEqual(rows["base"][3], "0.02M")
            self.assertEqual(rows["base"][4], "0.50")
            self.assertEqual(rows["faster"][4], "0.50")
            for row in rows.values():
                self.assertEqual(len(row), len(columns))
                self.assertTrue(row[-1].endswith(" s"), row)


if __name__ == "__main__":
    unittest.main()
