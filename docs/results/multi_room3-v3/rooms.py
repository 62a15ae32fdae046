#!/usr/bin/python3
"""Where the final policies of a multi_room3 grid go: for each finished cell,
EPISODES episodes of its policy.pb (`imca_env rollout --json`, seeds 1..EPISODES),
and per method the share of episodes in which each door opened and each room
held an agent at some step. Rooms of multi_room3_mace (docs/scenarios.md): left
(col < 15), right top (rows 0-9), right middle = the target (rows 11-19),
right bottom (rows 21-29), all at col >= 16.

  PYTHONPATH=tools docs/results/multi_room3-v3/rooms.py results/multi_room3-v3 > docs/results/multi_room3-v3/rooms.md
"""
import collections
import json
import os
import subprocess
import sys

from imca_tools import experiment

EPISODES = 20
ROOMS = ["left", "right top", "right middle (target)", "right bottom"]
DOORS = ["A", "B", "C", "D"]


def room(row, col):
    if col < 15:
        return "left"
    if col == 15:
        return None  # the wall's doors
    return "right top" if row < 10 else "right middle (target)" if 10 < row < 20 else "right bottom" if row > 20 else None


def episode(binary, policy, seed):
    out = subprocess.run([binary, "rollout", "--scenario", "multi_room3_mace", "--policy", policy, "--json",
                          "--seed", str(seed)], capture_output=True, text=True, check=True).stdout
    rooms, doors = set(), set()
    for line in out.splitlines():
        state = json.loads(line)
        rooms |= {room(a["row"], a["col"]) for a in state["agents"]}
        doors |= {DOORS[d] for d, is_open in enumerate(state["doors_open"]) if is_open}
    return rooms, doors


def main():
    results = sys.argv[1]
    binary = os.path.join(os.environ.get("IMCA_BIN", "build/bin"), "imca_env")
    by_method = collections.defaultdict(collections.Counter)
    run_count = collections.Counter()
    for cell in experiment.expand(experiment.load_saved_grid(results)["entries"], "grid.json"):
        folder = experiment.cell_dir(results, cell)
        if not experiment.finished(folder, cell):
            continue  # unfinished or interrupted: as the tables count cells
        method = f"{cell['reward']} {cell['credit']}" if cell["credit"] != "none" else "none"
        run_count[method] += 1
        for seed in range(1, EPISODES + 1):
            rooms, doors = episode(binary, os.path.join(folder, "policy.pb"), seed)
            by_method[method].update(rooms | {f"door {d}" for d in doors})
    columns = [f"door {d}" for d in DOORS] + ROOMS[1:]
    print(f"Share of {EPISODES} episodes per run (final policy, `imca_env rollout`) in which each door opened "
          "and each room on the right held an agent at some step; every episode starts in the left room.\n")
    print("| method | runs | " + " | ".join(columns) + " |")
    print("|---" * (len(columns) + 2) + "|")
    for method in ["none", "count shared", "count imca", "rnd shared", "rnd imca"]:
        if run_count[method]:
            total = run_count[method] * EPISODES
            print(f"| {method} | {run_count[method]} | " +
                  " | ".join(f"{100 * by_method[method][c] / total:.0f}%" for c in columns) + " |")


if __name__ == "__main__":
    main()
