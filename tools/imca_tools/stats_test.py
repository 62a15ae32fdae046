"""imca_tools.stats against values worked by hand."""
import math
import unittest

from imca_tools import stats


class IqmTest(unittest.TestCase):
    def test_drops_a_quarter_of_the_runs_at_each_end(self):
        self.assertEqual(stats.iqm([8, 1, 7, 2, 6, 3, 5, 4]), 4.5)  # (3 + 4 + 5 + 6) / 4
        self.assertEqual(stats.iqm([10, 1, 2, 3]), 2.5)  # (2 + 3) / 2
        self.assertEqual(stats.iqm([0, 1, 2, 3, 100]), 2.0)  # floor(5 / 4) = 1 cut: (1 + 2 + 3) / 3
        self.assertEqual(stats.iqm([0, 1, 2]), 1.0)  # floor(3 / 4) = 0: the mean
        # Ten runs (the headline cells): the middle six.
        self.assertAlmostEqual(stats.iqm([0, 0, 0.2, 0.4, 0.5, 0.6, 0.7, 0.9, 1, 1]), 3.3 / 6)

    def test_pooled_over_tasks(self):
        self.assertEqual(stats.pooled_iqm([[1, 2], [3, 4]]), 2.5)

    def test_no_runs_is_an_error(self):
        with self.assertRaises(ValueError):
            stats.iqm([])
        with self.assertRaises(ValueError):
            stats.pooled_iqm([[1], []])


class StepsTest(unittest.TestCase):
    def test_a_run_that_never_got_there_counts_as_the_budget(self):
        self.assertEqual(stats.steps_or_budget([100, None, float("nan"), 7], 1000), [100, 1000, 1000, 7])


class BootstrapTest(unittest.TestCase):
    def test_two_runs_give_the_three_resample_means(self):
        # Resampled means of [0, 1]: 0 (p 1/4), 0.5 (1/2), 1 (1/4), so the
        # 2.5% and 97.5% percentiles are 0 and 1.
        point, low, high = stats.stratified_bootstrap_ci([[0, 1]], lambda t: t[0].mean())
        self.assertEqual((point, low, high), (0.5, 0.0, 1.0))

    def test_resamples_stay_within_their_task(self):
        # Every stratified resample of these has mean 0.5; pooling the runs
        # would not (a resample of [0, 0, 1, 1] can be all zeros).
        mean = lambda t: sum(task.sum() for task in t) / sum(task.size for task in t)
        self.assertEqual(stats.stratified_bootstrap_ci([[0, 0], [1, 1]], mean), (0.5, 0.5, 0.5))
        point, low, high = stats.stratified_bootstrap_ci([[0, 0, 1, 1]], mean)
        self.assertEqual(point, 0.5)
        self.assertLess(low, 0.5)
        self.assertGreater(high, 0.5)

    def test_the_seed_fixes_the_interval(self):
        runs = [[0.1, 0.5, 0.9, 0.3, 0.7, 0.2, 0.8, 0.4, 0.6, 1.0]]
        a = stats.stratified_bootstrap_ci(runs, lambda t: stats.iqm(t[0]), seed=3)
        self.assertEqual(a, stats.stratified_bootstrap_ci(runs, lambda t: stats.iqm(t[0]), seed=3))
        self.assertNotEqual(a, stats.stratified_bootstrap_ci(runs, lambda t: stats.iqm(t[0]), seed=4))
        self.assertLessEqual(a[1], a[0])
        self.assertLessEqual(a[0], a[2])

    def test_bad_arguments(self):
        with self.assertRaises(ValueError):
            stats.stratified_bootstrap_ci([[1.0]], lambda t: 0.0, resamples=0)
        with self.assertRaises(ValueError):
            stats.stratified_bootstrap_ci([[1.0]], lambda t: 0.0, level=1.0)


class ProfileTest(unittest.TestCase):
    def test_fraction_of_runs_above_each_threshold(self):
        self.assertEqual(stats.performance_profile([0, 0.5, 1.0, 1.0], [0, 0.5, 0.9, 1.0]), [0.75, 0.5, 0.5, 0.0])


class ImprovementTest(unittest.TestCase):
    def test_pairs_with_ties_as_halves(self):
        # (1>0) + (1>2: no) + (2>0) + (2=2: half) = 2.5 of 4 pairs.
        self.assertEqual(stats.probability_of_improvement([[1, 2]], [[0, 2]]), 0.625)
        self.assertEqual(stats.probability_of_improvement([[0, 2]], [[1, 2]]), 0.375)
        # The mean over tasks: (0.625 + 1) / 2.
        self.assertEqual(stats.probability_of_improvement([[1, 2], [5]], [[0, 2], [3]]), 0.8125)

    def test_interval_of_a_method_always_better_is_one(self):
        self.assertEqual(stats.probability_of_improvement_ci([[3, 4, 5]], [[0, 1, 2]]), (1.0, 1.0, 1.0))
        point, low, high = stats.probability_of_improvement_ci([[1, 2]], [[0, 2]])
        self.assertEqual(point, 0.625)
        self.assertTrue(0 <= low <= point <= high <= 1)
        self.assertFalse(math.isclose(low, high))

    def test_tasks_must_pair(self):
        with self.assertRaises(ValueError):
            stats.probability_of_improvement([[1], [2]], [[1]])


if __name__ == "__main__":
    unittest.main()
