"""./imca experiment past one machine: a grid's cells as a Slurm job array or
a Kubernetes Indexed Job, and the state of every cell (docs/experiments.md,
"On a cluster").

A submission is a file DIR/submissions/<n>.json holding the cells it runs,
in index order (their whole definitions, so a task needs nothing else).
Task i of a Slurm array, or the pod of completion index i of an Indexed Job,
runs cell i through `python3 -m imca_tools.experiment --run-cell FILE --out
DIR` (run_cell): the cell's whole `./imca train` (reward server, learner and
actors on the task's node over loopback, under the same supervision) in
DIR/cells/<cell>/, exactly as a local grid runs it. A cell already finished
is left as it is; an unfinished one starts over. So a submission holds only
the cells that are neither finished nor queued or running in an earlier one,
and submitting the same grid again resumes it, as a local rerun does.

Slurm's state comes from its own commands (squeue for queued and running
tasks, `scontrol show job` for tasks that ended, while slurmctld keeps
them); the run folders say which cells finished.
"""
import datetime
import hashlib
import json
import os
import re
import shlex
import signal
import socket
import subprocess
import sys
import time

from . import binaries, runner, runs
from .grid import ExperimentError, cell_dir, cell_id, deterministic, only

BACKENDS = ("local", "slurm", "k8s")
# Resources per task when neither the grid's "resources" nor a flag sets them:
# one run keeps about two cores busy (runner.default_jobs) and peaks
# under 2 GB (LibTorch, the replay of one iteration, three processes).
DEFAULT_RESOURCES = {"cpus_per_task": 2, "mem": "4G", "time": "", "partition": ""}
# Slurm states of a task that is queued or running (squeue --states).
LIVE_STATES = {"PENDING", "CONFIGURING", "RUNNING", "COMPLETING", "SUSPENDED", "REQUEUED", "RESIZING",
               "REQUEUE_HOLD", "REQUEUE_FED", "SIGNALING", "STAGE_OUT", "STOPPED", "RESV_DEL_HOLD"}
# Where the Indexed Job's pods see the results claim and the submission.
K8S_RESULTS = "/results"
K8S_QUEUE = "/etc/imca/queue"
# A task's exit code when its cell cannot run as given (a bad submission,
# flags ./imca train refuses, a deterministic cell on other CPU kernels than
# the grid's): retrying cannot help.
EXIT_REFUSED = 2


def submissions_dir(out):
    return os.path.join(out, "submissions")


def load_submissions(out):
    """Every submission of DIR, oldest first (a file that cannot be read is skipped)."""
    found = []
    folder = submissions_dir(out)
    for name in os.listdir(folder) if os.path.isdir(folder) else []:
        if re.fullmatch(r"\d+\.json", name):
            record = runs.read_json(os.path.join(folder, name))
            if isinstance(record, dict) and isinstance(record.get("cells"), list):
                found.append(record)
    return sorted(found, key=lambda r: r["number"])


def new_submission(out, backend, cells):
    """Writes DIR/submissions/<n>.json for `cells` (index order) and returns the record."""
    os.makedirs(submissions_dir(out), exist_ok=True)
    number = max([r["number"] for r in load_submissions(out)], default=0) + 1
    record = {"number": number, "backend": backend, "job": None,
              "submitted": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
              "cells": cells}
    save_submission(out, record)
    return record


def submission_path(out, record):
    return os.path.join(submissions_dir(out), f"{record['number']}.json")


def save_submission(out, record):
    runs.write_json_atomically(submission_path(out, record), record)


def check(args, grid):
    """The backend's settings, before anything is written (ExperimentError naming the flag or key)."""
    resources(grid, args)
    if args.k8s_out and (not args.k8s_out.startswith(K8S_RESULTS + "/") or ".." in args.k8s_out.split("/")):
        raise ExperimentError(f"--k8s-out: must lie under {K8S_RESULTS}/ (where the claim is mounted)")
    if args.backend == "k8s" and not re.fullmatch(r"[a-z0-9][-a-z0-9]*", args.claim):
        raise ExperimentError(f"--claim: '{args.claim}' is not a Kubernetes name (lower case, digits, '-')")


def resources(grid, args):
    """Resources per task: the flag, else the grid's "resources", else DEFAULT_RESOURCES."""
    given = grid.get("resources", {})
    if not isinstance(given, dict) or set(given) - set(DEFAULT_RESOURCES):
        raise ExperimentError(f"grid 'resources' must be an object with keys {', '.join(DEFAULT_RESOURCES)}")
    chosen = {}
    for key, default in DEFAULT_RESOURCES.items():
        flag = getattr(args, key)
        value = flag if flag not in (None, "") else given.get(key, default)
        if key == "cpus_per_task" and (not isinstance(value, int) or isinstance(value, bool) or value < 1):
            raise ExperimentError(f"grid 'resources': cpus_per_task must be a positive integer, got {value!r}")
        if key != "cpus_per_task" and not isinstance(value, str):
            raise ExperimentError(f"grid 'resources': {key} must be a string, got {value!r}")
        chosen[key] = value
    if chosen["mem"] and not re.fullmatch(r"[1-9]\d*[KMGT]?", chosen["mem"], re.I):
        raise ExperimentError(f"--mem: '{chosen['mem']}' is not a size such as 4G or 4000M")
    return chosen


# --- The task: one cell of a submission ------------------------------------------------

def task_index(given):
    """The cell index of this task: --index, else Slurm's array task id, else
    the Indexed Job's completion index."""
    if given is not None:
        return given
    for name in ("SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"):
        if os.environ.get(name, "").isdigit():
            return int(os.environ[name])
    raise ExperimentError("--run-cell: no --index, SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX says which cell")


def run_cell(queue_file, index, out):
    """Runs cell `index` of the submission `queue_file` into OUT/cells/<cell>/
    and returns the exit code: 0 once the cell is finished (at once if it
    already was), else the train run's code (1 if it ended unfinished).
    SIGTERM or SIGINT (scancel, a pod's deletion) stop the run's services in
    order; the cell is then unfinished and a later submission runs it again."""
    record = runs.read_json(queue_file)
    if not isinstance(record, dict) or not isinstance(record.get("cells"), list):
        raise ExperimentError(f"--run-cell: '{queue_file}' is not a submission (a 'cells' list)")
    index = task_index(index)
    if not 0 <= index < len(record["cells"]):
        raise ExperimentError(f"--run-cell: index {index} is outside the submission's {len(record['cells'])} cells")
    cell = record["cells"][index]
    run_dir = cell_dir(out, cell)
    where = f"{socket.gethostname()}, submission {record.get('number')} task {index}"
    lock = runner.lock_cell(out, cell)
    if lock is None:
        print(f"imca experiment: cell {cell_id(cell)} is running in another process; this task leaves it "
              f"({where})", flush=True)
        return 1
    with lock:
        if runner.finished(run_dir, cell):
            print(f"imca experiment: cell {cell_id(cell)} is already finished ({where})", flush=True)
            return 0
        print(f"imca experiment: cell {cell_id(cell)} starts ({where}); log {run_dir}/train.log", flush=True)
        proc = runner.start_cell(cell, run_dir)
        stop = lambda *_: proc.poll() is None and proc.send_signal(signal.SIGTERM)
        signal.signal(signal.SIGTERM, stop)
        signal.signal(signal.SIGINT, stop)
        conflict = None
        # A deterministic cell runs on the grid's kernels (runner.check_kernels),
        # checked until its servers have all named theirs.
        while deterministic(cell) and proc.poll() is None:
            conflict, settled = runner.check_kernels(out, cell, run_dir)
            if conflict:
                stop()
            if conflict or settled:
                break
            time.sleep(0.5)
        code = proc.wait()
    if conflict:
        runner.note_refusal(run_dir, conflict)
        print(f"imca experiment: {conflict} ({where})", flush=True)
        return EXIT_REFUSED  # The node's CPU kernels: a retry on it would be refused again.
    summary = runner.finished(run_dir, cell)
    if summary is None:
        print(f"imca experiment: cell {cell_id(cell)} did not finish (exit {code}): "
              f"{runner.last_line(os.path.join(run_dir, 'train.log'))}", flush=True)
        # Not EXIT_REFUSED: a run that started and failed may succeed on a retry.
        return 1
    print(f"imca experiment: cell {cell_id(cell)} finished: success {summary['final_success_rate']:.0%}", flush=True)
    return 0


def task_command(queue_file, out):
    """The argv every task runs (its index from the environment)."""
    return ["python3", "-m", "imca_tools.experiment", "--run-cell", queue_file, "--out", out]


# --- Slurm -----------------------------------------------------------------------------

def slurm_command(argv):
    """Runs a Slurm client command; (returncode, stdout, stderr). A missing
    client is a one-line error."""
    try:
        r = subprocess.run(argv, capture_output=True, text=True, timeout=120)
    except FileNotFoundError:
        raise ExperimentError(f"--backend slurm: '{argv[0]}' is not on PATH (Slurm's client commands, "
                              "Debian package slurm-client)") from None
    except subprocess.TimeoutExpired:
        raise ExperimentError(f"--backend slurm: '{' '.join(argv[:2])}' did not answer in 120 s") from None
    return r.returncode, r.stdout, r.stderr


def slurm_query(argv):
    """stdout of a Slurm query, "" if Slurm no longer knows the job; any
    other failure (controller down, no answer) is an ExperimentError: a
    job Slurm cannot be asked about is not taken for one that ended."""
    code, stdout, stderr = slurm_command(argv)
    if code == 0:
        return stdout
    if "Invalid job id" in stderr:
        return ""
    why = (stderr.strip().splitlines() or [f"exit {code}"])[-1]
    raise ExperimentError(f"{argv[0]} cannot tell the state of job {argv[-1] if argv[0] == 'scontrol' else argv[4]}: "
                          f"{why}")


def slurm_tasks(job):
    """{task index: (state, reason or exit code)} of array job `job` as Slurm
    knows it: squeue's queued and running tasks, then `scontrol show job`'s
    ended ones (kept MinJobAge seconds after they end). {} once forgotten."""
    tasks = {}
    for line in slurm_query(["squeue", "-h", "-r", "-j", str(job), "-o", "%i|%T|%r"]).splitlines():
        task, state, reason = (line.split("|") + ["", ""])[:3]
        _, _, index = task.partition("_")
        if index.isdigit():
            tasks[int(index)] = (state, reason if reason not in ("None", "") else "")
    for line in slurm_query(["scontrol", "show", "job", "-o", str(job)]).splitlines():
        fields = dict(re.findall(r"(\w+)=(\S*)", line))
        # Pending tasks are squeue's (scontrol shortens their index list).
        if fields.get("ArrayJobId") != str(job) or fields.get("JobState") == "PENDING":
            continue
        index = fields.get("ArrayTaskId", "")
        if index.isdigit() and int(index) not in tasks:
            tasks[int(index)] = (fields.get("JobState", "UNKNOWN"), f"exit {fields.get('ExitCode', '?')}")
    return tasks


def live_cells(out, records):
    """{cell id: (record, index, state)} of cells queued or running in a Slurm submission."""
    live = {}
    for record in records:
        if record["backend"] != "slurm" or record.get("job") is None:
            continue
        for index, (state, _) in slurm_tasks(record["job"]).items():
            if state in LIVE_STATES and index < len(record["cells"]):
                live[cell_id(record["cells"][index])] = (record, index, state)
    return live


def slurm_log(out, record, index):
    return os.path.join(out, "logs", f"{record['number']}-{index}.log")


KERNEL_VARIABLES = ("OPENBLAS_CORETYPE", "ATEN_CPU_CAPABILITY")


def kernel_pins():
    """The submitter's choice of CPU kernels (OPENBLAS_CORETYPE,
    ATEN_CPU_CAPABILITY), where set, for every task: a deterministic cell
    replays only on the kernels it ran, and nodes of several CPU kinds pick
    several (docs/learner.md, "Deterministic runs")."""
    return {k: os.environ[k] for k in KERNEL_VARIABLES if os.environ.get(k)}


def task_script(out, record):
    """The batch script of a submission: the environment ./imca gives its
    tools and kernel_pins, then the task command. Nodes must see the clone
    (its tools and build/bin) and DIR at the same paths (a shared
    filesystem)."""
    env = {"IMCA_ROOT": binaries.ROOT, "IMCA_BIN": binaries.BIN, "PYTHONPATH": binaries.TOOLS, **kernel_pins()}
    lines = ["#!/bin/bash",
             f"# imca experiment submission {record['number']}: task i runs cell i of "
             f"{os.path.basename(submission_path(out, record))} (tools/imca_tools/cluster.py).",
             *(f"export {k}={shlex.quote(v)}" for k, v in env.items()),
             "exec " + shlex.join(["/usr/bin/python3"] + task_command(submission_path(out, record), out)[1:]), ""]
    path = os.path.join(submissions_dir(out), f"{record['number']}.sh")
    with open(path, "w") as f:
        f.write("\n".join(lines))
    os.chmod(path, 0o755)
    return path


def submit_slurm(out, grid_name, todo, res, jobs, extra):
    """One job array for `todo` (cells); returns the submission record."""
    record = new_submission(out, "slurm", todo)
    os.makedirs(os.path.join(out, "logs"), exist_ok=True)
    script = task_script(out, record)
    argv = ["sbatch", "--parsable", f"--array=0-{len(todo) - 1}" + (f"%{jobs}" if jobs else ""),
            f"--job-name=imca-{grid_name}", f"--cpus-per-task={res['cpus_per_task']}",
            f"--output={os.path.join(out, 'logs', str(record['number']) + '-%a.log')}", f"--chdir={out}"]
    argv += [f"--mem={res['mem']}"] if res["mem"] else []
    argv += [f"--time={res['time']}"] if res["time"] else []
    argv += [f"--partition={res['partition']}"] if res["partition"] else []
    argv += list(extra) + [script]
    try:
        code, stdout, stderr = slurm_command(argv)
        if code != 0:
            why = (stderr.strip().splitlines() or [f"exit {code}"])[-1]
            raise ExperimentError(f"sbatch refused the array: {why}")
    except ExperimentError:
        # Nothing was queued (an sbatch that timed out may have queued it:
        # squeue --name imca-<grid> tells).
        os.remove(submission_path(out, record))
        os.remove(script)
        raise
    record["job"] = stdout.strip().split(";")[0]
    record["sbatch"] = argv
    save_submission(out, record)
    return record


def wait_slurm(out, record, poll):
    """Blocks until no task of `record` is queued or running, printing each cell as it ends."""
    reported = set()
    while True:
        tasks = slurm_tasks(record["job"])
        live = {i for i, (state, _) in tasks.items() if state in LIVE_STATES}
        for index, cell in enumerate(record["cells"]):
            if index in live or index in reported:
                continue
            reported.add(index)
            summary = runner.finished(cell_dir(out, cell), cell)
            state = f"success {summary['final_success_rate']:.0%}" if summary else \
                f"FAILED ({tasks.get(index, ('ended', ''))[0]})"
            print(f"[{len(reported)}/{len(record['cells'])}] {cell_id(cell)}: {state}", file=sys.stderr, flush=True)
        if not live:
            return
        time.sleep(poll)


# --- Kubernetes ------------------------------------------------------------------------

def k8s_name(out, number):
    """A DNS-1123 name for a submission's Job and ConfigMap: the results
    folder's name, a digest of its path (two folders of one preset never
    share a Job) and the submission's number."""
    base = re.sub(r"[^a-z0-9-]+", "-", os.path.basename(out).lower()).strip("-")[:30].strip("-") or "grid"
    return f"imca-{base}-{hashlib.sha1(out.encode()).hexdigest()[:6]}-{number}"


def k8s_quantity(mem):
    """Slurm's size (4G, 4000M, 4000: megabytes) as a Kubernetes quantity (4Gi, 4000Mi)."""
    number, unit = re.fullmatch(r"(\d+)([KMGT]?)", mem.upper()).groups()
    return number + {"": "Mi", "K": "Ki", "M": "Mi", "G": "Gi", "T": "Ti"}[unit]


def queue_text(record):
    """A submission as the pods read it: JSON, one cell a line."""
    cells = ",\n".join("  " + json.dumps(cell, sort_keys=True) for cell in record["cells"])
    return f'{{"number": {record["number"]}, "backend": {json.dumps(record["backend"])}, "cells": [\n{cells}\n]}}\n'


def k8s_manifest(record, out, res, jobs, image, claim, results_dir):
    """[ConfigMap, Job]: the submission's cells, and an Indexed Job whose pod of
    completion index i runs cell i into `results_dir` on the claim `claim`,
    with kernel_pins in its environment."""
    name = k8s_name(out, record["number"])
    labels = {"app.kubernetes.io/name": "imca-experiment", "imca/results": name.rsplit("-", 1)[0]}
    resources = {"requests": {"cpu": str(res["cpus_per_task"])}}
    if res["mem"]:
        resources["requests"]["memory"] = k8s_quantity(res["mem"])
        resources["limits"] = {"memory": k8s_quantity(res["mem"])}
    config_map = {"apiVersion": "v1", "kind": "ConfigMap", "metadata": {"name": name, "labels": labels},
                  "data": {"cells.json": queue_text(record)}}
    count = len(record["cells"])
    pins = kernel_pins()
    job = {
        "apiVersion": "batch/v1", "kind": "Job", "metadata": {"name": name, "labels": labels},
        "spec": {
            "completionMode": "Indexed",
            "completions": count,
            "parallelism": min(jobs or count, count),
            # Each cell is retried once on its own; a cell that fails twice
            # fails its index, not the grid (Kubernetes 1.29+: a 1.28 API
            # server drops the field unless its feature gate is on).
            "backoffLimitPerIndex": 1,
            "maxFailedIndexes": count,
            "podFailurePolicy": {"rules": [
                # An evicted or preempted pod is replaced without counting as
                # a failure of its cell (deploy/k8s's Jobs do the same).
                {"action": "Ignore", "onPodConditions": [{"type": "DisruptionTarget", "status": "True"}]},
                # Flags refused (exit 2): a retry would be refused again.
                {"action": "FailIndex", "onExitCodes": {"containerName": "cell", "operator": "In",
                                                        "values": [EXIT_REFUSED]}},
            ]},
            "template": {
                "metadata": {"labels": labels},
                "spec": {
                    "restartPolicy": "Never",
                    # The run stops its services in order on SIGTERM (within 270 s).
                    "terminationGracePeriodSeconds": 300,
                    "containers": [{
                        "name": "cell", "image": image, "imagePullPolicy": "IfNotPresent",
                        "command": task_command(f"{K8S_QUEUE}/cells.json", results_dir),
                        "resources": resources,
                        **({"env": [{"name": k, "value": v} for k, v in pins.items()]} if pins else {}),
                        "volumeMounts": [{"name": "results", "mountPath": K8S_RESULTS},
                                         {"name": "queue", "mountPath": K8S_QUEUE, "readOnly": True}],
                    }],
                    "volumes": [{"name": "results", "persistentVolumeClaim": {"claimName": claim}},
                                {"name": "queue", "configMap": {"name": name}}],
                },
            },
        },
    }
    return [config_map, job]


def manifest_text(docs):
    """The manifest's YAML: multi-line strings as blocks (the cells, one a
    line), repeated values in full (no anchors)."""
    import yaml  # python3-yaml is a host package: the image that runs --run-cell has none

    class Dumper(yaml.SafeDumper):
        def ignore_aliases(self, data):
            return True

    def text(dumper, value):
        return dumper.represent_scalar("tag:yaml.org,2002:str", value, style="|" if "\n" in value else None)

    Dumper.add_representer(str, text)
    return yaml.dump_all(docs, Dumper=Dumper, sort_keys=False)


def write_k8s(out, grid_name, todo, res, jobs, image, claim, results_dir):
    """Writes DIR/k8s/<n>.yaml for `todo`; returns (record, path)."""
    record = new_submission(out, "k8s", todo)
    docs = k8s_manifest(record, out, res, jobs, image, claim, results_dir)
    record["job"] = docs[1]["metadata"]["name"]
    save_submission(out, record)
    os.makedirs(os.path.join(out, "k8s"), exist_ok=True)
    path = os.path.join(out, "k8s", f"{record['number']}.yaml")
    with open(path, "w") as f:
        f.write(f"# imca experiment submission {record['number']}: {len(todo)} cells of grid {grid_name}\n"
                f"# kubectl apply -f {os.path.basename(path)}  (needs the claim {claim}: docs/experiments.md)\n")
        f.write(manifest_text(docs))
    return record, path


# --- Submitting and the state of every cell --------------------------------------------

def submit(args, grid, cells, out):
    """--backend slurm|k8s: submits the cells that are neither finished nor
    queued or running (only those --only names, if given). Returns the exit code."""
    unfinished = {cell_id(c) for c, _ in runner.unfinished_cells(cells, out)}
    res = resources(grid, args)
    records = load_submissions(out)
    live = live_cells(out, records) if args.backend == "slurm" else {}
    todo = [c for c in only(cells, args.only) if cell_id(c) not in live and cell_id(c) in unfinished]
    finished = len(cells) - len(unfinished)
    print(f"imca experiment: {len(cells)} cells, {finished} finished, {len(live)} queued or running, "
          f"{len(todo)} to submit; results in {out}", file=sys.stderr, flush=True)
    if not todo:
        return 0
    if args.backend == "slurm":
        record = submit_slurm(out, grid["name"], todo, res, args.jobs, args.sbatch_arg)
        print(f"imca experiment: submitted Slurm array job {record['job']} ({len(todo)} tasks; logs in "
              f"{os.path.join(out, 'logs')}); see ./imca experiment --status {out}", file=sys.stderr, flush=True)
        if args.wait:
            try:
                wait_slurm(out, record, args.poll_seconds)
            except KeyboardInterrupt:
                raise ExperimentError(f"stopped waiting; job {record['job']} goes on (--status {out}; "
                                      f"scancel {record['job']} stops it)") from None
        return 0
    results_dir = args.k8s_out or f"{K8S_RESULTS}/{os.path.basename(out)}"
    earlier = [r for r in records if r["backend"] == "k8s" and any(cell_id(c) in {cell_id(t) for t in todo}
                                                                   for c in r["cells"])]
    if earlier:
        print(f"imca experiment: note: Job {earlier[-1]['job']} had cells that are not finished in {out}; "
              "delete it first if it still runs (kubectl delete job), or copy its finished cells back: a "
              "cell that runs in two pods at once is refused by the second", file=sys.stderr)
    record, path = write_k8s(out, grid["name"], todo, res, args.jobs, args.image, args.claim, results_dir)
    print(f"imca experiment: wrote {path} (Indexed Job {record['job']}, {len(todo)} cells)", file=sys.stderr)
    if args.apply:
        try:
            r = subprocess.run(["kubectl", "apply", "-f", path], capture_output=True, text=True, timeout=300)
        except FileNotFoundError:
            raise ExperimentError("--apply: 'kubectl' is not on PATH; the manifest is written, apply it "
                                  "where kubectl reaches your cluster") from None
        if r.returncode != 0:
            raise ExperimentError(f"kubectl apply failed: {(r.stderr.strip().splitlines() or ['?'])[-1]}")
        print(r.stdout.strip(), file=sys.stderr)
    return 0


def cell_states(out, cells):
    """[(cell id, state, detail)] for the grid's cells: done, running,
    pending, failed (Slurm's state and the last log line) or not run."""
    records = load_submissions(out)
    tasks = {}  # record number -> {index: (state, detail)}
    latest = {}  # cell id -> (record, index): its last submission
    for record in records:
        for index, cell in enumerate(record["cells"]):
            latest[cell_id(cell)] = (record, index)
    for record, _ in latest.values():
        if record["backend"] == "slurm" and record.get("job") and record["number"] not in tasks:
            tasks[record["number"]] = slurm_tasks(record["job"])
    states = []
    for cell in cells:
        cid = cell_id(cell)
        run_dir = os.path.join(out, "cells", cid)
        summary = runner.finished(run_dir, cell)
        if summary:
            states.append((cid, "done", f"success {summary['final_success_rate']:.0%}"))
            continue
        record, index = latest.get(cid, (None, None))
        where = ""
        if record is not None:
            where = f"{record['backend']} submission {record['number']}"
            if record["backend"] == "slurm":
                where = f"job {record['job']}_{index}"
                state, detail = tasks.get(record["number"], {}).get(index, ("", ""))
                if state in LIVE_STATES:
                    states.append((cid, "pending" if state == "PENDING" else "running",
                                   f"{where} {state.lower()}" + (f" ({detail})" if detail else "")))
                    continue
                if state:
                    where += f" {state}"
        if record is None:
            # Never submitted: not run, or a local run that is running or stopped.
            states.append((cid, "unfinished", runner.last_line(os.path.join(run_dir, "train.log")))
                          if os.path.isdir(run_dir) else (cid, "not run", ""))
            continue
        if record["backend"] == "k8s":
            # Kubernetes' own state is kubectl's to tell (docs/experiments.md).
            states.append((cid, "submitted", where))
            continue
        log = os.path.join(run_dir, "train.log")
        if not os.path.exists(log):
            log = slurm_log(out, record, index)  # The task ended before the run started.
        states.append((cid, "failed", f"{where}: {runner.last_line(log)}"))
    return states


def print_status(out, cells):
    states = cell_states(out, cells)
    width = max(len(cid) for cid, _, _ in states)
    for cid, state, detail in states:
        print(f"{cid:<{width}}  {state:<9}  {detail}".rstrip())
    counts = {}
    for _, state, _ in states:
        counts[state] = counts.get(state, 0) + 1
    print(f"{len(states)} cells: " + ", ".join(f"{n} {state}" for state, n in sorted(counts.items())))
    if counts.get("failed"):
        print("resubmit what is missing with the same command, or one cell with --only CELL")
    return 0
