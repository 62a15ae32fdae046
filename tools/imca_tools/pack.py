"""A grid's finished cells, small enough to commit: for each cell whose
summary.json says it reached its budget, config.json, summary.json and the
report's columns of metrics.csv, with the grid's grid.json, in one tar.xz.
Unpacked into the results folder, `./imca experiment --report DIR` rewrites
the same tables and the same preset command resumes after the packed cells
(the rest of a cell folder, checkpoints and policies, is not kept).

  PYTHONPATH=tools python3 -m imca_tools.pack results/frontier-v3 docs/results/frontier-v3/cells.tar.xz
  mkdir -p results/frontier-v3 && tar -xJf docs/results/frontier-v3/cells.tar.xz -C results/frontier-v3
"""
import csv
import io
import os
import sys
import tarfile

from . import runs
from .grid import cell_dir, cell_id, expand, load_saved_grid
from .runner import finished

# What the report reads of metrics.csv (tools/imca_tools/report.py); the rest
# stays in the cell folders.
COLUMNS = ["iteration", "env_steps", "wall_seconds", "success_rate", "episode_return"]


def add(tar, name, data):
    info = tarfile.TarInfo(name)
    info.size, info.mtime = len(data), 0
    tar.addfile(info, io.BytesIO(data))


def read(path):
    with open(path, "rb") as f:
        return f.read()


def main(out, archive):
    packed = 0
    with tarfile.open(archive, "w:xz") as tar:
        add(tar, "grid.json", read(os.path.join(out, "grid.json")))
        grid = load_saved_grid(out)
        for cell_spec in expand(grid["entries"], "grid.json"):
            run_dir, cell = cell_dir(out, cell_spec), cell_id(cell_spec)
            if not finished(run_dir, cell_spec):
                continue
            for name in ("config.json", "summary.json"):
                add(tar, f"cells/{cell}/{name}", read(os.path.join(run_dir, name)))
            rows = runs.read_metrics(os.path.join(run_dir, "metrics.csv"))
            text = io.StringIO()
            writer = csv.DictWriter(text, fieldnames=[c for c in COLUMNS if rows and c in rows[0]],
                                    extrasaction="ignore", lineterminator="\n")
            writer.writeheader()
            writer.writerows(rows)
            add(tar, f"cells/{cell}/metrics.csv", text.getvalue().encode())
            packed += 1
    print(f"{packed} finished cells -> {archive} ({os.path.getsize(archive):,} bytes)")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: python3 -m imca_tools.pack RESULTS_DIR ARCHIVE.tar.xz")
    main(sys.argv[1], sys.argv[2])
