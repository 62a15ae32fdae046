#!/usr/bin/python3
"""./imca experiment (imca_tools.experiment) against the real binaries."""
import csv
import json
import os
import re
import signal
import subprocess
import tempfile
import time
import unittest

from imca_tools import binaries, grid, presets, runner
from imca_tools.grid import cell_id  # where a cell's run folder is

ROOT = os.environ.get("IMCA_ROOT", os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EXPERIMENT = binaries.module_argv("experiment")

SMALL = {"actors": 1, "envs-per-actor": 8, "unroll-length": 32, "batch-steps": 1024}


def cell_dir(out, credit):
    cell = {"scenario": "coop_nav", "reward": "count", "credit": credit, "permutation": "off", "seed": 1,
            "steps": 16000, "flags": SMALL}
    return os.path.join(out, "cells", cell_id(cell))


def grid_file(directory, entries, name="tiny"):
    path = os.path.join(directory, "grid.json")
    with open(path, "w") as f:
        json.dump({"name": name, "entries": entries}, f)
    return path


class PresetsTest(unittest.TestCase):
    def test_maddpg_rows_parse_and_are_labelled_by_their_algorithm(self):
        for preset in ("paper", "edti"):
            cells = grid.expand(presets.presets()[preset]["entries"], preset)
            grid.check_flags(cells)  # Every cell's flags are valid ./imca train flags.
            label = grid.labeller(cells)
            labels = {label(cell) for cell in cells}
            self.assertTrue({"maddpg none", "maddpg imca", "none", "imca"} <= labels, (preset, labels))
            maddpg = [cell for cell in cells if cell["flags"].get("algo") == "maddpg"]
            self.assertEqual(len(maddpg), (3 if preset == "paper" else 2) * 2 * 5, preset)
            # MAPPO's cells keep their ids (and so their finished runs).
            self.assertIn("coop_nav-count-imca-off-s1-2000k" if preset == "paper" else "pass-count-imca-off-s1-3000k",
                          {grid.cell_id(cell) for cell in cells})

    def test_seed_by_seed_presets_hold_whole_seeds_of_every_method(self):
        for preset, per_seed, seeds in (("frontier", 25, 10), ("multi_room3", 5, 5)):
            cells = grid.expand(presets.presets()[preset]["entries"], preset)
            grid.check_flags(cells)
            self.assertEqual(len(cells), per_seed * seeds, preset)
            self.assertEqual(len({grid.cell_id(cell) for cell in cells}), len(cells), preset)
            # Any prefix of whole seeds holds every method: seed k's cells come before seed k+1's.
            self.assertEqual([cell["seed"] for cell in cells],
                             [seed for seed in range(1, seeds + 1) for _ in range(per_seed)], preset)
            self.assertTrue(all(cell["flags"].get("deterministic") for cell in cells), preset)
        label = grid.labeller(cells)  # multi_room3: the reward kind names each bonus.
        self.assertEqual({(cell["reward"], label(cell)) for cell in cells},
                         {("count", "none"), ("count", "shared"), ("count", "imca"), ("rnd", "shared"),
                          ("rnd", "imca")})


class ExperimentErrorsTest(unittest.TestCase):
    def check_one_line(self, entries, *words):
        with tempfile.TemporaryDirectory() as tmp:
            r = subprocess.run(EXPERIMENT + ["--grid", grid_file(tmp, entries), "--out", os.path.join(tmp, "out")],
                               capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            for word in words:
                self.assertIn(word, r.stderr)
            self.assertFalse(os.path.exists(os.path.join(tmp, "out", "cells")), "nothing may run")

    def test_bad_grids_are_one_line_errors_naming_the_key(self):
        self.check_one_line([{"scenario": "coop_nav", "reward": "count", "credit": ["shared", "imcaa"]}],
                            "entry 0", "credit 'imcaa'")
        self.check_one_line([{"scenario": "coop_nav", "reward": "count"}], "missing 'credit'")
        self.check_one_line([{"scenario": "coop_nav", "reward": "count", "credit": "imca", "steps": 0}], "steps")
        self.check_one_line([{"scenario": "coop_nav", "reward": "count", "credit": "imca", "sed": 1}],
                            "unknown key 'sed'")
        self.check_one_line([{"scenario": "coop_nav", "reward": "count", "credit": "imca",
                              "flags": {"temperature": 0}}], "--temperature")
        self.check_one_line([{"scenario": "coop_nav", "reward": "count", "credit": "imca",
                              "flags": {"steps": 5000}}], "flag 'steps'", "entry's 'steps'")
        self.check_one_line([{"scenario": "coop_nav", "reward": "count", "credit": "imca",
                              "flags": {"reward_port": 5000}}], "flag 'reward-port'")
        self.check_one_line([{"scenario": "coop_nav", "reward": "count", "credit": "imca",
                              "flags": {"envs_per_actor": 4, "envs-per-actor": 8}}], "twice")

    def test_cells_run_with_other_defaults_are_not_mixed_in(self):
        # A finished cell whose config.json records another value of a
        # ./imca train setting (e.g. from before a change of defaults).
        with tempfile.TemporaryDirectory() as tmp:
            entries = [{"scenario": "coop_nav", "reward": "count", "credit": "shared", "seed": 1,
                        "steps": 16000, "flags": SMALL}]
            out = os.path.join(tmp, "out")
            run_dir = cell_dir(out, "shared")
            os.makedirs(run_dir)
            with open(os.path.join(run_dir, "summary.json"), "w") as f:
                json.dump({"env_steps": 16384, "interrupted": False, "final_success_rate": 0.0}, f)
            with open(os.path.join(run_dir, "config.json"), "w") as f:
                json.dump({"batch_steps": 1024, "lr": 0.123, "objective_added_later": 1}, f)
            r = subprocess.run(EXPERIMENT + ["--grid", grid_file(tmp, entries), "--out", out],
                               capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertIn("lr 0.123 where ./imca train now uses 0.001", r.stderr)
            self.assertIn("another --out", r.stderr)

    def test_unreadable_grid_names_the_flag(self):
        r = subprocess.run(EXPERIMENT + ["--grid", "/nonexistent/grid.json"], capture_output=True, text=True)
        self.assertEqual(r.returncode, 2)
        self.assertIn("--grid", r.stderr)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)


class ExperimentRunTest(unittest.TestCase):
    def test_runs_resumes_after_ctrl_c_and_reports(self):
        with tempfile.TemporaryDirectory() as tmp:
            entries = [{"scenario": "coop_nav", "reward": "count", "credit": ["shared", "imca"], "seed": 1,
                        "steps": 16000, "flags": SMALL}]
            out = os.path.join(tmp, "out")
            argv = EXPERIMENT + ["--grid", grid_file(tmp, entries), "--out", out, "--jobs", "1"]
            first_cell = os.path.join(cell_dir(out, "shared"), "summary.json")
            proc = subprocess.Popen(argv, stderr=subprocess.PIPE, text=True)
            deadline = time.time() + 240
            while not os.path.exists(first_cell) and time.time() < deadline and proc.poll() is None:
                time.sleep(0.05)
            self.assertTrue(os.path.exists(first_cell), "the first cell never finished")
            time.sleep(0.5)  # The second cell is starting or running.
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=240)
            self.assertEqual(proc.returncode, 130, err)
            self.assertIn("the same command resumes", err)

            r = subprocess.run(argv, capture_output=True, text=True, timeout=300)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertIn("2 cells, 1 already finished, 1 to run", r.stderr)
            with open(os.path.join(out, "runs.csv")) as f:
                runs = list(csv.DictReader(f))
            self.assertEqual([row["finished"] for row in runs], ["True", "True"])
            with open(os.path.join(out, "table.md")) as f:
                table = f.read()
            self.assertIn("| coop_nav | count | shared | 1/1 |", table)
            self.assertIn("| coop_nav | count | imca | 1/1 |", table)
            # The statistics: one run a cell, flagged as too few for a headline.
            with open(os.path.join(out, "stats.md")) as f:
                stats_md = f.read()
            self.assertIn("| coop_nav | count | shared | 1 * |", stats_md)
            self.assertIn("| coop_nav | count | imca | 1 * |", stats_md)
            self.assertIn("Probability of improvement on coop_nav + count", stats_md)
            with open(os.path.join(out, "stats.csv")) as f:
                stats_rows = list(csv.DictReader(f))
            improvement = {(r["method"], r["over"]): float(r["point"]) for r in stats_rows
                           if r["statistic"] == "probability_of_improvement_final_success"}
            self.assertEqual(set(improvement), {("shared", "imca"), ("imca", "shared")})
            self.assertAlmostEqual(improvement["shared", "imca"] + improvement["imca", "shared"], 1.0)
            self.assertEqual({(r["method"], r["over"]) for r in stats_rows
                              if r["statistic"] == "probability_of_improvement_steps_to_90"},
                             {("shared", "imca"), ("imca", "shared")})
            for name in ["table.csv", "curves-coop_nav-count.png", "shares-coop_nav-count.png",
                         "profile-coop_nav-count.png", "gifs/coop_nav-count-imca.gif", "grid.json"]:
                self.assertTrue(os.path.exists(os.path.join(out, name)), name)
            trace = os.path.join(cell_dir(out, "imca"), "credit_trace.csv")
            with open(trace) as f:
                rows = list(csv.DictReader(f))
            self.assertGreater(len(rows), 0)
            self.assertEqual({row["agent"] for row in rows}, {"0", "1"})
            for t in {row["t"] for row in rows}:
                shares = [float(row["share"]) for row in rows if row["t"] == t]
                self.assertAlmostEqual(sum(shares), 1.0, places=4)

            r = subprocess.run(argv, capture_output=True, text=True, timeout=120)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertIn("2 cells, 2 already finished, 0 to run", r.stderr)

    def test_a_deterministic_cell_on_other_kernels_than_the_grids_is_refused(self):
        # Seed 1 runs on OpenBLAS's Prescott kernels; seed 2 then starts on
        # Haswell's, which would not replay seed 1's machine: the grid stops
        # it and says which kernels. Once they are the grid's, it runs.
        with tempfile.TemporaryDirectory() as tmp:
            flags = dict(SMALL, deterministic=True)
            entries = [{"scenario": "coop_nav", "reward": "count", "credit": "shared", "seed": [1, 2],
                        "steps": 16000, "flags": flags}]
            out = os.path.join(tmp, "out")
            argv = EXPERIMENT + ["--grid", grid_file(tmp, entries), "--out", out, "--jobs", "1"]
            cell = {"scenario": "coop_nav", "reward": "count", "credit": "shared", "permutation": "off",
                    "steps": 16000, "flags": flags}
            first, second = (cell_id(dict(cell, seed=seed)) for seed in (1, 2))
            prescott = dict(os.environ, OPENBLAS_CORETYPE="Prescott", ATEN_CPU_CAPABILITY="default")
            haswell = dict(os.environ, OPENBLAS_CORETYPE="Haswell", ATEN_CPU_CAPABILITY="avx2")
            r = subprocess.run(argv + ["--only", first], capture_output=True, text=True, timeout=300, env=prescott)
            self.assertEqual(r.returncode, 0, r.stderr)

            r = subprocess.run(argv, capture_output=True, text=True, timeout=300, env=haswell)
            self.assertEqual(r.returncode, 2, r.stderr)
            last = r.stderr.strip().splitlines()[-1]
            # Whichever server says first (the reward server starts first).
            self.assertRegex(last, re.escape(second) + "'s (learner|reward_server) runs " + re.escape(
                f"'aten=avx2 openblas=Haswell' where the grid's cells run 'aten=default openblas=Prescott' "
                f"(set by {first})"))
            self.assertIn("OPENBLAS_CORETYPE", last)
            self.assertIsNone(runner.finished(os.path.join(out, "cells", second), dict(cell, seed=2)),
                              "the refused cell must not finish")
            # The first cell to name its kernels set the grid's; --status shows why the cell stopped.
            with open(os.path.join(out, "kernels.json")) as f:
                self.assertEqual(json.load(f)["cell"], first)
            r = subprocess.run(EXPERIMENT + ["--status", out], capture_output=True, text=True, timeout=60)
            self.assertIn("runs 'aten=avx2 openblas=Haswell'", r.stdout + r.stderr)
            # --only runs the one cell, against the whole grid's kernels.
            r = subprocess.run(argv + ["--only", second], capture_output=True, text=True, timeout=300, env=haswell)
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertIn(f"(set by {first})", r.stderr.strip().splitlines()[-1])

            r = subprocess.run(argv, capture_output=True, text=True, timeout=300, env=prescott)
            self.assertEqual(r.returncode, 0, r.stderr)
            with open(os.path.join(out, "cells", second, "summary.json")) as f:
                self.assertEqual(json.load(f)["kernels"], {"learner": "aten=default openblas=Prescott",
                                                           "reward_server": "aten=default openblas=Prescott"})

if __name__ == "__main__":
    unittest.main()
