"""report's tasks and statistics on small fixtures: which methods a task
compares, across reward kinds and budgets, and what stats.md/stats.csv say."""
import csv
import os
import tempfile
import unittest

from imca_tools import report


def runs(budget, *results):
    """A group's members: (cell, summary) per (final success, steps to 90% or None)."""
    return [({"steps": budget}, {"final_success_rate": success, "steps_to_90pct_success": steps})
            for success, steps in results]


# pass: count shared always solves at 1M, EDTI never; imca in between.
GROUPS = {
    ("pass", "count", "shared"): runs(3_000_000, (1.0, 1_000_000), (1.0, 1_000_000)),
    ("pass", "count", "imca"): runs(3_000_000, (1.0, 2_000_000), (0.0, None)),
    ("pass", "edti", "edti"): runs(3_000_000, (0.0, None), (0.0, None)),
    ("coop_nav", "count", "shared"): runs(2_000_000, (1.0, 400_000)),
    ("coop_nav", "count", "imca"): runs(2_000_000, (1.0, 500_000)),
    ("coop_nav", "count", "imca/random"): runs(4_000_000, (1.0, 300_000)),
}


class TasksTest(unittest.TestCase):
    def test_a_task_is_a_scenario_at_one_budget_across_reward_kinds(self):
        tasks = report.tasks_of(GROUPS)
        self.assertEqual(set(tasks), {("pass", 3_000_000), ("coop_nav", 2_000_000), ("coop_nav", 4_000_000)})
        p = tasks["pass", 3_000_000]
        self.assertEqual((p["name"], p["file"], p["reward"]), ("pass", "pass", ""))
        self.assertEqual(list(p["methods"].values()), ["count shared", "count imca", "edti"])
        c = tasks["coop_nav", 2_000_000]
        self.assertEqual((c["name"], c["file"], c["reward"]),
                         ("coop_nav + count at 2,000,000 env steps", "coop_nav-count-2000k", "count"))
        self.assertEqual(list(c["methods"].values()), ["shared", "imca"])

    def test_maddpg_labels_keep_their_reward_kind(self):
        groups = {("pass", "count", "maddpg imca"): runs(1, (1.0, 1)),
                  ("pass", "eiti", "maddpg eiti"): runs(1, (1.0, 1))}
        self.assertEqual(list(report.tasks_of(groups)["pass", 1]["methods"].values()),
                         ["count maddpg imca", "maddpg eiti"])


class StatsTest(unittest.TestCase):
    def test_probability_of_improvement_across_reward_kinds(self):
        with tempfile.TemporaryDirectory() as out:
            report.write_stats(out, GROUPS)
            with open(os.path.join(out, "stats.md")) as f:
                md = f.read()
            with open(os.path.join(out, "stats.csv")) as f:
                rows = list(csv.DictReader(f))
        self.assertIn("Probability of improvement on pass (final success)", md)
        self.assertIn("| | count shared | count imca | edti |", md)
        # coop_nav's two budgets are two tasks; the one of a single method has no table.
        self.assertIn("Probability of improvement on coop_nav + count at 2,000,000 env steps", md)
        self.assertNotIn("at 4,000,000 env steps", md)
        p = {(r["method"], r["over"], r["statistic"]): (float(r["point"]), float(r["low"]), float(r["high"]))
             for r in rows if r["statistic"].startswith("probability_of_improvement")}
        # Every shared run beats every EDTI run: 1 on every resample.
        self.assertEqual(p["count shared", "edti", "probability_of_improvement_final_success"], (1.0, 1.0, 1.0))
        self.assertEqual(p["edti", "count shared", "probability_of_improvement_final_success"], (0.0, 0.0, 0.0))
        # imca (1.0, 0.0) over EDTI (0.0, 0.0): pairs win 2 of 4, tie 2: 0.75.
        self.assertEqual(p["count imca", "edti", "probability_of_improvement_final_success"][0], 0.75)
        # Steps to 90%, fewer is better, never = the budget: imca (2M, 3M)
        # over shared (1M, 1M) loses every pair.
        self.assertEqual(p["count imca", "count shared", "probability_of_improvement_steps_to_90"][0], 0.0)
        # Both EDTI runs count as the budget, as does imca's second: a tie there.
        self.assertEqual(p["count imca", "edti", "probability_of_improvement_steps_to_90"][0], 0.75)
        # The rows of a mixed task name no reward kind; one of one kind names it.
        rewards = {(r["scenario"], r["reward"]) for r in rows if r["statistic"].startswith("probability")}
        self.assertEqual(rewards, {("pass", ""), ("coop_nav", "count")})

    def test_profile_per_task(self):
        with tempfile.TemporaryDirectory() as out:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            for task in report.tasks_of(GROUPS).values():
                report.profile_plot(out, task, GROUPS, plt)
            self.assertEqual(sorted(os.listdir(out)),
                             ["profile-coop_nav-count-2000k.png", "profile-coop_nav-count-4000k.png",
                              "profile-pass.png"])


if __name__ == "__main__":
    unittest.main()
