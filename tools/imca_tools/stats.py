"""Statistics of runs as the field now reports them.

After Agarwal et al. (NeurIPS 2021, "Deep RL at the Edge of the
Statistical Precipice"; the rliable library) and InstaDeep's marl-eval:
the interquartile mean (IQM) instead of the mean, percentile intervals of
stratified bootstrap resamples instead of Student t, performance profiles,
and the probability of improvement of one method over another.

Scores come as a list of 1-D sequences, one per task (a task: a scenario and
reward kind), each holding one value per run. A statistic over one task is
the case of a one-element list. Stratified: a bootstrap resample draws each
task's runs with replacement from that task's runs alone, so tasks keep
their run counts and never trade runs.
"""
import numpy as np

DEFAULT_RESAMPLES = 2000
DEFAULT_LEVEL = 0.95


def _tasks(scores):
    tasks = [np.asarray(task, dtype=float) for task in scores]
    if not tasks or any(task.ndim != 1 or task.size == 0 for task in tasks):
        raise ValueError("scores: want one non-empty 1-D sequence of runs per task")
    return tasks


def iqm(values):
    """Interquartile mean: the mean of the values left after dropping
    floor(n / 4) of the lowest and as many of the highest (as
    scipy.stats.trim_mean(x, 0.25), which rliable uses)."""
    x = np.sort(np.asarray(values, dtype=float).ravel())
    if x.size == 0:
        raise ValueError("iqm of no values")
    cut = int(0.25 * x.size)
    return float(x[cut:x.size - cut].mean())


def pooled_iqm(scores):
    """IQM over every run of every task (rliable's aggregate IQM)."""
    return iqm(np.concatenate(_tasks(scores)))


def steps_or_budget(steps, budget):
    """Env steps to a threshold per run, with a run that never got there (None
    or NaN) counted as the budget: a censored value, so an IQM of these is a
    lower bound wherever the budget enters it."""
    out = []
    for s in steps:
        missing = s is None or (isinstance(s, float) and np.isnan(s))
        out.append(float(budget) if missing else float(s))
    return out


def stratified_bootstrap_ci(scores, statistic, resamples=DEFAULT_RESAMPLES, seed=0, level=DEFAULT_LEVEL):
    """(point, low, high): statistic(scores) and the percentile interval at
    `level` of statistic over `resamples` stratified bootstrap resamples drawn
    from numpy's default generator seeded with `seed` (the same arguments
    give the same interval). `statistic` takes a list of 1-D arrays, one per
    task."""
    tasks = _tasks(scores)
    if resamples < 1:
        raise ValueError("resamples must be >= 1")
    if not 0 < level < 1:
        raise ValueError("level must be in (0, 1)")
    rng = np.random.default_rng(seed)
    values = np.empty(resamples)
    for r in range(resamples):
        values[r] = statistic([task[rng.integers(0, task.size, task.size)] for task in tasks])
    tail = (1 - level) / 2
    low, high = np.quantile(values, [tail, 1 - tail])
    return float(statistic(tasks)), float(low), float(high)


def performance_profile(values, thresholds):
    """For each threshold tau, the fraction of runs scoring above tau (the
    run-score distribution of rliable: P(X > tau))."""
    x = np.asarray(values, dtype=float).ravel()
    if x.size == 0:
        raise ValueError("performance profile of no runs")
    return [float(np.mean(x > tau)) for tau in thresholds]


def probability_of_improvement(x_scores, y_scores):
    """P(X > Y): the mean over tasks of the probability that a run of method X
    scores above a run of method Y on that task, a tie counting one half (the
    Mann-Whitney U over n m, as rliable)."""
    xs, ys = _tasks(x_scores), _tasks(y_scores)
    if len(xs) != len(ys):
        raise ValueError(f"probability of improvement: {len(xs)} tasks against {len(ys)}")
    per_task = []
    for x, y in zip(xs, ys):
        greater = (x[:, None] > y[None, :]).mean()
        ties = (x[:, None] == y[None, :]).mean()
        per_task.append(greater + 0.5 * ties)
    return float(np.mean(per_task))


def probability_of_improvement_ci(x_scores, y_scores, resamples=DEFAULT_RESAMPLES, seed=0, level=DEFAULT_LEVEL):
    """(point, low, high) of probability_of_improvement, the interval from
    stratified bootstrap resamples of both methods' runs (each task's runs of
    each method drawn from themselves)."""
    xs, ys = _tasks(x_scores), _tasks(y_scores)
    if len(xs) != len(ys):
        raise ValueError(f"probability of improvement: {len(xs)} tasks against {len(ys)}")
    k = len(xs)
    # One stratified resample of the 2k strata: X's tasks, then Y's.
    return stratified_bootstrap_ci(xs + ys, lambda t: probability_of_improvement(t[:k], t[k:]), resamples, seed,
                                   level)
