"""Tables and plots of an experiment folder (written by ./imca experiment at
the end of a grid, and alone by `./imca experiment --report DIR`, which
`python3 -m imca_tools.report DIR` is).

Per (scenario, reward, method): mean and 95% confidence interval (Student t
over seeds) of the final success rate, env steps to 80% and 90% success
(mean over the seeds that got there, and how many did), wall time; learning
curves with 95% bands; per-agent credit shares of an imca run; GIFs.

And stats.md / stats.csv, the statistics reviewers now ask for
(imca_tools.stats): per cell the IQM of final success and of env steps to
90% (a run that never got there counted as the budget) with stratified
bootstrap 95% intervals; per task the probability that each method's run
beats each other's, with its interval; and a performance profile per task
(profile-SCENARIO-REWARD.png, or profile-SCENARIO.png where the task's
methods use several reward kinds: the fraction of runs above each final
success). A task is a scenario at one budget (tasks_of).
"""
import collections
import csv
import math
import os
import shutil
import statistics
import sys

from . import options, runner, runs, stats
from .grid import ExperimentError, cell_dir, cell_id, expand, labeller, load_saved_grid

# Bootstrap resamples and their generator's seed: the same runs give the
# same intervals.
RESAMPLES = 2000
BOOTSTRAP_SEED = 0
# Runs per cell below which a cell's figures are flagged as no headline.
HEADLINE_RUNS = 10

# Two-sided 95% Student t quantiles by degrees of freedom (1..30).
T95 = [12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145,
       2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048,
       2.045, 2.042]


def mean_ci(values):
    """(mean, half-width of the 95% CI); half-width None for one value."""
    m = statistics.mean(values)
    if len(values) < 2:
        return m, None
    t = T95[len(values) - 2] if len(values) - 1 <= len(T95) else 1.96
    return m, t * statistics.stdev(values) / math.sqrt(len(values))


def read_metrics(run_dir):
    return runs.read_metrics(os.path.join(run_dir, "metrics.csv"))


def groups_of(cells, summaries, method):
    """{(scenario, reward, method): [(cell, summary or None)]} in grid order."""
    groups = {}
    for cell in cells:
        key = (cell["scenario"], cell["reward"], method(cell))
        groups.setdefault(key, []).append((cell, summaries.get(cell_id(cell))))
    return groups


def fmt_pct(m, h):
    """Mean and its 95% CI, clipped to [0, 100%] (a rate cannot leave it)."""
    if h is None:
        return f"{m:.0%}"
    return f"{m:.0%} [{max(0.0, m - h):.0%}, {min(1.0, m + h):.0%}]"


def fmt_steps(row, pct):
    reached, total = row[f"reached_{pct}"], row["seeds_done"]
    if not reached:
        return f"- (0/{total})"
    m, h = row[f"steps_to_{pct}_mean"], row[f"steps_to_{pct}_ci95"]
    text = f"{m / 1e6:.2f}M" + ("" if h is None else f" ± {h / 1e6:.2f}M")
    return f"{text} ({reached}/{total})"


def write(out, cells, summaries, method):
    groups = groups_of(cells, summaries, method)
    write_runs_csv(out, cells, summaries, method)
    rows = []
    for (scenario, reward, label), members in groups.items():
        done = [(c, s) for c, s in members if s is not None]
        row = {"scenario": scenario, "reward": reward, "method": label, "seeds_done": len(done),
               "seeds": len(members), "budget": members[0][0]["steps"]}
        if done:
            m, h = mean_ci([s["final_success_rate"] for _, s in done])
            row.update(success_mean=m, success_ci95=h)
            for pct in (80, 90):
                hits = [s[f"steps_to_{pct}pct_success"] for _, s in done
                        if s[f"steps_to_{pct}pct_success"] is not None]
                row[f"steps_to_{pct}_mean"], row[f"steps_to_{pct}_ci95"] = mean_ci(hits) if hits else (None, None)
                row[f"reached_{pct}"] = len(hits)
            row["wall_seconds_mean"] = statistics.mean(s["wall_seconds"] for _, s in done)
            # Wall-clock to 90% (training's own clock), median over the
            # seeds that got there (summaries from before it was written: none).
            walls = [s["wall_to_90pct_success"] for _, s in done if s.get("wall_to_90pct_success") is not None]
            row["wall_to_90_median"] = statistics.median(walls) if walls else None
            row["steps_per_second"] = statistics.mean(s["env_steps"] / max(s["wall_seconds"], 1e-9) for _, s in done)
            # The training episodes' mean team return at the end (the
            # dense-reward tasks' measure; the last metrics row's window).
            finals = [float(rows_[-1]["episode_return"]) for rows_ in
                      (read_metrics(cell_dir(out, c)) for c, _ in done) if rows_]
            if finals:
                row["return_mean"], row["return_ci95"] = mean_ci(finals)
        rows.append(row)
    write_table_csv(out, rows)
    write_table_md(out, rows)
    write_stats(out, groups)
    plots(out, groups, method)


def fmt_interval(point, low, high, fmt):
    return f"{fmt(point)} [{fmt(low)}, {fmt(high)}]"


# The statistics the probability of improvement is reported on, and how
# stats.md names them.
POI_STATISTICS = {"final_success": "final success",
                  "steps_to_90": "env steps to 90% success, fewer is better; never counts as the budget"}


def tasks_of(groups):
    """The tasks methods are compared on, in groups' order: {(scenario,
    budget): {"name", "file", "scenario", "budget", "reward" (its one reward
    kind, or empty), "methods": {group key: label}}}. A task is a
    scenario at one budget, whatever the novelty: a reward kind is part of
    the method (count imca against EDTI on pass is the comparison). Where a
    task's methods use several reward kinds, each label names its reward
    ("count imca"; "edti", "maddpg eiti" for a method named by its reward)."""
    tasks = {}
    for key, members in groups.items():
        tasks.setdefault((key[0], members[0][0]["steps"]), []).append(key)
    budgets = collections.Counter(scenario for scenario, _ in tasks)
    named = {}
    for (scenario, budget), keys in tasks.items():
        rewards = sorted({reward for _, reward, _ in keys})
        if len(rewards) == 1:
            name, file = f"{scenario} + {rewards[0]}", f"{scenario}-{rewards[0]}"
            labels = {key: key[2] for key in keys}
        else:
            name, file = scenario, scenario
            labels = {key: key[2] if key[1] in key[2].split(" ") else f"{key[1]} {key[2]}" for key in keys}
        if budgets[scenario] > 1:
            name, file = f"{name} at {budget:,} env steps", f"{file}-{budget // 1000}k"
        named[scenario, budget] = {"name": name, "file": file, "methods": labels, "scenario": scenario,
                                   "budget": budget, "reward": rewards[0] if len(rewards) == 1 else ""}
    return named


def write_stats(out, groups):
    """stats.csv and stats.md: IQMs with intervals per cell, and the
    probability of improvement between the methods of each task
    (tasks_of)."""
    cells, scores = [], {}
    for (scenario, reward, label), members in groups.items():
        done = [s for _, s in members if s is not None]
        if not done:
            continue
        budget = members[0][0]["steps"]
        success = [s["final_success_rate"] for s in done]
        steps90 = stats.steps_or_budget([s["steps_to_90pct_success"] for s in done], budget)
        iqm_of = lambda t: stats.iqm(t[0])
        cells.append({
            "scenario": scenario, "reward": reward, "method": label, "runs": len(done), "budget": budget,
            "success": stats.stratified_bootstrap_ci([success], iqm_of, RESAMPLES, BOOTSTRAP_SEED),
            "steps_to_90": stats.stratified_bootstrap_ci([steps90], iqm_of, RESAMPLES, BOOTSTRAP_SEED),
            "reached_90": sum(s["steps_to_90pct_success"] is not None for s in done)})
        # Scores where higher is better: final success, and fewer env steps to 90%.
        scores[scenario, reward, label] = {"final_success": success, "steps_to_90": [-s for s in steps90]}
    tasks = []  # (task, [(group key, label)] of the methods with finished runs)
    for task in tasks_of(groups).values():
        methods = [(key, label) for key, label in task["methods"].items() if key in scores]
        if len(methods) >= 2:
            tasks.append((task, methods))
    improvements = []
    for task, methods in tasks:
        for i, (x_key, x_label) in enumerate(methods):
            for y_key, y_label in methods[i + 1:]:
                for statistic in POI_STATISTICS:
                    # P(Y > X) = 1 - P(X > Y), on the same resamples.
                    p, low, high = stats.probability_of_improvement_ci(
                        [scores[x_key][statistic]], [scores[y_key][statistic]], RESAMPLES, BOOTSTRAP_SEED)
                    common = {"task": task["name"], "scenario": task["scenario"], "reward": task["reward"],
                              "budget": task["budget"], "statistic": statistic}
                    improvements += [dict(common, method=x_label, over=y_label, p=(p, low, high)),
                                     dict(common, method=y_label, over=x_label, p=(1 - p, 1 - high, 1 - low))]
    with open(os.path.join(out, "stats.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["scenario", "reward", "method", "over", "runs", "budget", "statistic", "point", "low", "high"])
        for c in cells:
            for name in ("success", "steps_to_90"):
                w.writerow([c["scenario"], c["reward"], c["method"], "", c["runs"], c["budget"],
                            f"iqm_{'final_success' if name == 'success' else name}", *c[name]])
        for i in improvements:
            w.writerow([i["scenario"], i["reward"], i["method"], i["over"], "", i["budget"],
                        f"probability_of_improvement_{i['statistic']}", *i["p"]])
    lines = [f"Interquartile means (IQM) over runs, with 95% percentile intervals of {RESAMPLES:,} stratified "
             f"bootstrap resamples (seed {BOOTSTRAP_SEED}); imca_tools.stats.", "",
             "| scenario | reward | method | runs | final success: IQM [95% CI] "
             "| env steps to 90%: IQM [95% CI] | runs that reached 90% |",
             "|---|---|---|---|---|---|---|"]
    for c in cells:
        flag = "" if c["runs"] >= HEADLINE_RUNS else " *"
        lines.append(f"| {c['scenario']} | {c['reward']} | {c['method']} | {c['runs']}{flag} "
                     f"| {fmt_interval(*c['success'], lambda v: f'{v:.0%}')} "
                     f"| {fmt_interval(*c['steps_to_90'], lambda v: f'{v / 1e6:.2f}M')} "
                     f"| {c['reached_90']}/{c['runs']} |")
    lines += ["", "Env steps to 90%: a run that never got there counts as its budget, so where such runs "
              "fall in the middle half the IQM is a lower bound. "
              f"*: fewer than {HEADLINE_RUNS} runs, too few for a headline claim."]
    for task, methods in tasks:
        labels = [label for _, label in methods]
        for statistic, what in POI_STATISTICS.items():
            lines += ["", f"Probability of improvement on {task['name']} ({what}): "
                      "P(a run of the row's method beats one of the column's), ties count half, [95% CI].", "",
                      "| | " + " | ".join(labels) + " |", "|---" * (len(labels) + 1) + "|"]
            table = {(i["method"], i["over"]): i["p"] for i in improvements
                     if (i["task"], i["statistic"]) == (task["name"], statistic)}
            for x_label in labels:
                row = [fmt_interval(*table[x_label, y_label], lambda v: f"{v:.2f}") if x_label != y_label else "-"
                       for y_label in labels]
                lines.append(f"| {x_label} | " + " | ".join(row) + " |")
    with open(os.path.join(out, "stats.md"), "w") as f:
        f.write("\n".join(lines) + "\n")


def write_runs_csv(out, cells, summaries, method):
    fields = ["cell", "scenario", "reward", "method", "credit", "permutation", "seed", "budget", "finished",
              "final_success_rate", "steps_to_80pct_success", "steps_to_90pct_success", "wall_seconds",
              "env_steps_per_sec", "wall_to_90pct_success"]
    with open(os.path.join(out, "runs.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for cell in cells:
            s = summaries.get(cell_id(cell))
            w.writerow({"cell": cell_id(cell), "scenario": cell["scenario"], "reward": cell["reward"],
                        "method": method(cell), "credit": cell["credit"], "permutation": cell["permutation"],
                        "seed": cell["seed"], "budget": cell["steps"], "finished": s is not None,
                        **({k: s.get(k) for k in fields[9:]} if s else {})})


def write_table_csv(out, rows):
    fields = ["scenario", "reward", "method", "seeds_done", "seeds", "budget", "success_mean", "success_ci95",
              "steps_to_80_mean", "steps_to_80_ci95", "reached_80", "steps_to_90_mean", "steps_to_90_ci95",
              "reached_90", "wall_seconds_mean", "steps_per_second", "return_mean", "return_ci95",
              "wall_to_90_median"]
    with open(os.path.join(out, "table.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)


def write_table_md(out, rows):
    lines = ["| scenario | reward | method | seeds | final success: mean [95% CI] | env steps to 80% "
             "| env steps to 90% | final return: mean [95% CI] | wall time / run | env steps/s | wall time to 90% |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["seeds_done"] == 0:
            lines.append(f"| {r['scenario']} | {r['reward']} | {r['method']} | 0/{r['seeds']} | not run yet "
                         "| | | | | | |")
            continue
        final_return = "-"
        if r.get("return_mean") is not None:
            final_return = f"{r['return_mean']:.1f}"
            if r.get("return_ci95") is not None:  # None for one seed.
                final_return += (f" [{r['return_mean'] - r['return_ci95']:.1f}, "
                                 f"{r['return_mean'] + r['return_ci95']:.1f}]")
        wall90 = "-" if r.get("wall_to_90_median") is None else f"{r['wall_to_90_median']:.0f} s"
        lines.append(
            f"| {r['scenario']} | {r['reward']} | {r['method']} | {r['seeds_done']}/{r['seeds']} "
            f"| {fmt_pct(r['success_mean'], r['success_ci95'])} "
            f"| {fmt_steps(r, 80)} | {fmt_steps(r, 90)} | {final_return} "
            f"| {r['wall_seconds_mean']:.0f} s | {r['steps_per_second']:,.0f} "
            f"| {wall90} |")
    lines.append("")
    lines.append("Budget per run in env steps: " + ", ".join(
        sorted({f"{r['scenario']} {r['budget']:,}" for r in rows})) + ". Steps to 80%/90%: mean over the "
        "seeds that got there (how many did, in brackets). CI: Student t over seeds. Wall time to 90%: "
        "median over those seeds, training's own clock.")
    with open(os.path.join(out, "table.md"), "w") as f:
        f.write("\n".join(lines) + "\n")


def curve(rows, grid, key="success_rate"):
    """Step-hold interpolation of a metrics column onto `grid`."""
    xs = [int(r["env_steps"]) for r in rows]
    ys = [float(r[key]) for r in rows]
    out, j = [], -1
    for x in grid:
        while j + 1 < len(xs) and xs[j + 1] <= x:
            j += 1
        # Before the first row: no success yet; other columns hold their first value.
        out.append(ys[j] if j >= 0 else (0.0 if key == "success_rate" or not ys else ys[0]))
    return out


def plots(out, groups, method):
    # matplotlib is heavy: imported when something is to be drawn, not to
    # read or run a grid.
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenarios = {}
    for (scenario, reward, label), members in groups.items():
        scenarios.setdefault((scenario, reward), []).append((label, members))
    # A task with several reward kinds (the edti preset: count credit modes
    # against EITI and EDTI) also gets one plot of all its methods.
    for task in tasks_of(groups).values():
        if not task["reward"]:
            curves_figure(out, [(label, groups[key]) for key, label in task["methods"].items()], plt,
                          f"{task['name']}: mean and 95% CI over seeds", os.path.join(out, f"curves-{task['file']}.png"))
    gif_dir = os.path.join(out, "gifs")
    for (scenario, reward), methods in scenarios.items():
        if not any(s is not None for _, members in methods for _, s in members):
            continue  # Nothing finished yet for this scenario.
        curves_figure(out, methods, plt, f"{scenario} + {reward}: mean and 95% CI over seeds",
                      os.path.join(out, f"curves-{scenario}-{reward}.png"))
        curves_figure(out, methods, plt, f"{scenario} + {reward}: team return, mean and 95% CI over seeds",
                      os.path.join(out, f"returns-{scenario}-{reward}.png"), key="episode_return")
        # GIF of each method's final policy (its first finished seed).
        os.makedirs(gif_dir, exist_ok=True)
        for label, members in methods:
            for c, s in members:
                gif = os.path.join(out, "cells", cell_id(c), "episode.gif")
                if s is not None and os.path.exists(gif):
                    name = f"{scenario}-{reward}-{label.replace('/', '_').replace(' ', '_')}.gif"
                    shutil.copyfile(gif, os.path.join(gif_dir, name))
                    break
        shares_plot(out, scenario, reward, methods, plt)
    for task in tasks_of(groups).values():
        profile_plot(out, task, groups, plt)


def profile_plot(out, task, groups, plt):
    """A task's performance profile (profile-FILE.png, tasks_of): per method,
    the fraction of its runs whose final success is above each threshold."""
    thresholds = [i / 100 for i in range(101)]
    if not any(s is not None for key in task["methods"] for _, s in groups[key]):
        return  # Nothing finished yet for this task.
    fig, ax = plt.subplots(figsize=(7.5, 4))
    for key, label in task["methods"].items():
        members = groups[key]
        success = [s["final_success_rate"] for _, s in members if s is not None]
        if success:
            ax.step(thresholds, stats.performance_profile(success, thresholds), where="post", lw=1.6,
                    label=f"{label} ({len(success)})")
    ax.set_xlabel("final success rate threshold")
    ax.set_ylabel("fraction of runs above it")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.set_title(f"{task['name']}: performance profile", fontsize=10)
    # Outside the axes: lines at 0 and 1 sit where a legend inside would.
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1))
    fig.tight_layout()
    fig.savefig(os.path.join(out, f"profile-{task['file']}.png"), dpi=110)
    plt.close(fig)


def curves_figure(out, methods, plt, title, path, key="success_rate"):
    """A metrics column over env steps (evaluation success by default), one
    line (mean, 95% CI band) per method."""
    if not any(s is not None for _, members in methods for _, s in members):
        return
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for label, members in methods:
        curves = [read_metrics(cell_dir(out, c)) for c, s in members if s is not None]
        curves = [r for r in curves if r]
        if not curves:
            continue
        budget = members[0][0]["steps"]
        grid = [budget * i / 100 for i in range(101)]
        ys = [curve(r, grid, key) for r in curves]
        mean = [statistics.mean(col) for col in zip(*ys)]
        line, = ax.plot(grid, mean, lw=1.6, label=f"{label} ({len(curves)})")
        if len(curves) > 1:
            half = [mean_ci(list(col))[1] for col in zip(*ys)]
            low, high = (0, 1) if key == "success_rate" else (-math.inf, math.inf)
            ax.fill_between(grid, [max(low, m - h) for m, h in zip(mean, half)],
                            [min(high, m + h) for m, h in zip(mean, half)], color=line.get_color(), alpha=0.15)
    ax.set_xlabel("env steps")
    if key == "success_rate":
        ax.set_ylabel("evaluation success rate")
        ax.set_ylim(-0.02, 1.02)
    else:
        ax.set_ylabel(key.replace("_", " "))
    ax.grid(alpha=0.3)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8, loc="upper left" if key == "success_rate" else "lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def shares_plot(out, scenario, reward, methods, plt):
    """Credit shares of the first finished imca run: per agent over training
    (metrics.csv), and over one late training episode (credit_trace.csv)."""
    for label, members in methods:
        if not label.startswith("imca"):
            continue
        for c, s in members:
            run_dir = cell_dir(out, c)
            rows = read_metrics(run_dir)
            if s is None or not rows or "share_1" not in rows[0]:
                continue
            trace = runs.read_trace(run_dir)
            fig, axes = plt.subplots(1, 2 if trace else 1, figsize=(12 if trace else 6.5, 4))
            axes = axes if trace else [axes]
            n = sum(1 for k in rows[0] if k.startswith("share_") and k[6:].isdigit())
            steps = [int(r["env_steps"]) for r in rows]
            ax = axes[0]
            for a in range(1, n + 1):
                ax.plot(steps, [float(r[f"share_{a}"]) for r in rows], lw=1.2, label=f"agent {a}: mean p^a")
            ax.plot(steps, [float(r["share_max"]) for r in rows], lw=1.2, ls="--", color="k",
                    label="mean max_a p^a")
            ax.axhline(1 / n, color="grey", lw=0.8, ls=":")
            ax.set_xlabel("env steps")
            ax.set_title(f"credit shares over training ({label}, seed {c['seed']})", fontsize=10)
            ax.legend(fontsize=8)
            ax.grid(alpha=0.3)
            if trace:
                trace_panel(axes[1], trace, n)
            fig.tight_layout()
            fig.savefig(os.path.join(out, f"shares-{scenario}-{reward}.png"), dpi=110)
            plt.close(fig)
            return


def trace_panel(ax, trace, n):
    """p^a over the steps of one episode; a dot where agent a entered a cell it
    had not visited earlier in the episode (its exploring moves)."""
    on_new, on_old = [], []
    for a in range(n):
        rows = [r for r in trace if int(r["agent"]) == a]
        # Where the agent starts is not a new cell.
        seen = {rows[0]["cell"]} if rows else set()
        t = [int(r["t"]) for r in rows]
        p = [float(r["share"]) for r in rows]
        line, = ax.plot(t, p, lw=1.0, label=f"agent {a + 1}")
        new_t, new_p = [], []
        for r in rows:
            cell = r["next_cell"]
            if cell not in seen:
                seen.add(cell)
                new_t.append(int(r["t"]))
                new_p.append(float(r["share"]))
                on_new.append(float(r["share"]))
            else:
                on_old.append(float(r["share"]))
        ax.scatter(new_t, new_p, s=12, color=line.get_color(), zorder=3)
    ax.axhline(1 / n, color="grey", lw=0.8, ls=":")
    ax.set_xlabel("step of the episode")
    ax.set_ylabel("p^a")
    mean = lambda xs: f"{statistics.mean(xs):.3f}" if xs else "-"
    ax.set_title(f"one late training episode: p^a per step; dots: the agent entered a new cell\n"
                 f"mean p^a on those steps {mean(on_new)}, on the others {mean(on_old)}", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)


def write_grid(out, cells):
    """The tables and plots of `cells` (a grid's, imca_tools.grid) as OUT's
    cell folders hold them; returns {cell id: summary, None if unfinished}."""
    results = {cell_id(c): runner.finished(cell_dir(out, c), c) for c in cells}
    write(out, cells, results, labeller(cells))
    return results


def main(argv=None):
    """Only (re)write the tables and plots of an experiment folder DIR."""
    p = options.OneLineParser(prog="imca experiment --report", description=__doc__)
    p.add_argument("dir", metavar="DIR", help="an experiment folder (its grid.json and cells/)")
    args = p.parse_args(options.dashed(sys.argv[1:] if argv is None else argv))
    out = os.path.abspath(args.dir)
    try:
        write_grid(out, expand(load_saved_grid(out)["entries"], "grid.json"))
    except ExperimentError as error:
        print(f"imca experiment: {error}", file=sys.stderr)
        return 2
    print(f"imca experiment: table {os.path.join(out, 'table.md')}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
