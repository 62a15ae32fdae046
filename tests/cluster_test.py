#!/usr/bin/python3
"""./imca experiment on a cluster: --backend slurm on a real one-node Slurm
cluster, and --backend k8s's Indexed Job checked offline as deploy_test
checks deploy/k8s (no Kubernetes runs here).

SlurmTest starts its own munged, slurmctld and slurmd (Debian's slurm-wlm
22.05 and munge, packages tagged test) with a configuration, key, sockets and
ports of its own in a temporary folder: one node, this host. It runs a small
deterministic grid locally and as a job array, cancels one running task with
scancel, checks --status names that cell failed, resubmits (only that cell
runs again), compares every cell's run folder and the reports with the local
run's, and stops the daemons it started.
"""
import csv
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import unittest
import unittest.mock

import yaml

from imca_tools import binaries, cluster, presets, runner, same_run
from imca_tools.grid import cell_id, expand

EXPERIMENT = binaries.module_argv("experiment")
# A cell of about 20 s: long enough to be cancelled while it runs.
STEPS = 32000
SMALL = {"actors": 1, "envs_per_actor": 8, "unroll_length": 32, "batch_steps": 1024}
GRID = {"name": "cluster", "entries": [{"scenario": "coop_nav", "reward": "count", "credit": ["shared", "imca"],
                                        "seed": [1, 2], "steps": STEPS, "flags": dict(SMALL, deterministic=True)}]}
# Report columns that measure the machine, not the training.
WALL_COLUMNS = {"wall_seconds", "env_steps_per_sec", "wall_seconds_mean", "steps_per_second"}


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run(argv, timeout=600, **kwargs):
    return subprocess.run(argv, capture_output=True, text=True, timeout=timeout, **kwargs)


def environment_without_kernels():
    """This process's environment without the variables that choose CPU kernels."""
    return {k: v for k, v in os.environ.items() if k not in cluster.KERNEL_VARIABLES}


def write_grid(directory, grid=GRID):
    path = os.path.join(directory, "grid.json")
    with open(path, "w") as f:
        json.dump(grid, f)
    return path


def read_csv(path, drop=()):
    with open(path) as f:
        return [{k: v for k, v in row.items() if k not in drop} for row in csv.DictReader(f)]


class SlurmCluster:
    """munged, slurmctld and slurmd of a one-node cluster in `folder`."""

    def __init__(self, folder):
        self.folder = folder
        self.conf = os.path.join(folder, "slurm.conf")
        self.munge_socket = os.path.join(folder, "munge", "socket")
        self.env = dict(os.environ, SLURM_CONF=self.conf)

    def path(self, *parts):
        return os.path.join(self.folder, *parts)

    def start(self):
        for d in ("munge", "state", "spool", "log"):
            os.makedirs(self.path(d), mode=0o700, exist_ok=True)
        key = self.path("munge", "munge.key")
        subprocess.run(["mungekey", "--create", f"--keyfile={key}"], check=True)
        subprocess.run(["munged", "--force", f"--socket={self.munge_socket}", f"--key-file={key}",
                        f"--pid-file={self.path('munge', 'pid')}", f"--log-file={self.path('log', 'munged.log')}",
                        f"--seed-file={self.path('munge', 'seed')}"], check=True)
        host = socket.gethostname().split(".")[0]
        with open("/proc/meminfo") as f:
            mem_mb = int(re.search(r"MemTotal:\s+(\d+)", f.read()).group(1)) // 1024
        settings = {
            "ClusterName": "imcatest", "SlurmctldHost": f"{host}(127.0.0.1)", "SlurmUser": "root",
            "SlurmdUser": "root", "AuthType": "auth/munge", "CredType": "cred/munge",
            "AuthInfo": f"socket={self.munge_socket}", "SlurmctldPort": free_port(), "SlurmdPort": free_port(),
            "StateSaveLocation": self.path("state"), "SlurmdSpoolDir": self.path("spool"),
            "SlurmctldPidFile": self.path("slurmctld.pid"), "SlurmdPidFile": self.path("slurmd.pid"),
            "SlurmctldLogFile": self.path("log", "slurmctld.log"), "SlurmdLogFile": self.path("log", "slurmd.log"),
            # No cgroups (no systemd here): processes tracked by parentage.
            "ProctrackType": "proctrack/linuxproc", "TaskPlugin": "task/none",
            "SelectType": "select/cons_tres", "SelectTypeParameters": "CR_Core_Memory",
            "SchedulerType": "sched/backfill", "MpiDefault": "none", "ReturnToService": 2,
            "AccountingStorageType": "accounting_storage/none", "JobCompType": "jobcomp/none",
            "JobAcctGatherType": "jobacct_gather/none", "KillWait": 10, "MinJobAge": 600,
        }
        with open(self.conf, "w") as f:
            f.writelines(f"{k}={v}\n" for k, v in settings.items())
            f.write(f"NodeName={host} NodeAddr=127.0.0.1 CPUs={os.cpu_count()} RealMemory={mem_mb // 2} "
                    "State=UNKNOWN\n")
            f.write(f"PartitionName=test Nodes={host} Default=YES MaxTime=INFINITE State=UP\n")
        subprocess.run(["slurmctld", "-i"], check=True, env=self.env)
        subprocess.run(["slurmd", "-N", host], check=True, env=self.env)
        deadline = time.time() + 60
        while time.time() < deadline:
            r = run(["sinfo", "-h", "-o", "%T"], env=self.env)
            if r.returncode == 0 and r.stdout.strip() in ("idle", "mixed", "allocated"):
                return
            time.sleep(0.5)
        raise AssertionError(f"the node never came up: {r.stdout}{r.stderr}\n{self.logs()}")

    def logs(self):
        text = []
        for name in sorted(os.listdir(self.path("log"))):
            with open(self.path("log", name), errors="replace") as f:
                text.append(f"== {name}\n" + "".join(f.readlines()[-20:]))
        return "\n".join(text)

    def stop(self):
        """Cancels every job, waits for their tasks, stops the daemons (what start left half-up too)."""
        if os.path.exists(self.conf):
            run(["scancel", "--full", "--user", "root"], env=self.env, timeout=60)
            deadline = time.time() + 60
            while time.time() < deadline and run(["squeue", "-h"], env=self.env, timeout=60).stdout.strip():
                time.sleep(0.5)
            run(["scontrol", "shutdown"], env=self.env, timeout=60)
        pids = []
        for pid_file in ("slurmctld.pid", "slurmd.pid", os.path.join("munge", "pid")):
            try:
                with open(self.path(pid_file)) as f:
                    pids.append(int(f.read().split()[0]))
            except (OSError, ValueError, IndexError):
                pass
        subprocess.run(["munged", "--stop", f"--socket={self.munge_socket}"], capture_output=True)
        deadline = time.time() + 30
        for pid in pids:
            while time.time() < deadline and os.path.exists(f"/proc/{pid}"):
                time.sleep(0.2)
            if os.path.exists(f"/proc/{pid}"):
                os.kill(pid, 9)

    def tasks(self, job):
        """{index: state} of the array job's queued and running tasks."""
        r = run(["squeue", "-h", "-r", "-j", job, "-o", "%i|%T"], env=self.env)
        return {int(line.split("|")[0].split("_")[1]): line.split("|")[1]
                for line in r.stdout.splitlines() if "_" in line.split("|")[0]}


def task_starts(out):
    """{cell id: how many tasks started it}, from the tasks' logs."""
    starts = {}
    for name in os.listdir(os.path.join(out, "logs")):
        with open(os.path.join(out, "logs", name)) as f:
            for found in re.findall(r"cell (\S+) starts", f.read()):
                starts[found] = starts.get(found, 0) + 1
    return starts


@unittest.skipUnless(os.geteuid() == 0, "slurmd starts tasks as their user: it runs as root (./imca test does)")
class SlurmTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="imca-slurm-")
        cls.cluster = SlurmCluster(os.path.join(cls.tmp, "slurm"))
        t0 = time.time()
        try:
            cls.cluster.start()
        except BaseException:
            cls.cluster.stop()
            raise
        print(f"slurm: munged, slurmctld and slurmd up in {time.time() - t0:.1f} s", file=sys.stderr)

    @classmethod
    def tearDownClass(cls):
        cls.cluster.stop()
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def experiment(self, *argv, timeout=600):
        return run(EXPERIMENT + list(argv), timeout=timeout, env=self.cluster.env)

    def test_an_array_cancelled_in_part_and_resubmitted_ends_as_the_local_grid(self):
        grid = write_grid(self.tmp)
        local, cluster = os.path.join(self.tmp, "local"), os.path.join(self.tmp, "cluster")
        cells = expand(GRID["entries"], "test")

        t0 = time.time()
        r = self.experiment("--grid", grid, "--out", local, "--jobs", "2")
        self.assertEqual(r.returncode, 0, r.stderr)
        print(f"slurm: the grid locally, 2 at a time: {time.time() - t0:.0f} s", file=sys.stderr)

        t0 = time.time()
        submit = ["--grid", grid, "--out", cluster, "--backend", "slurm", "--cpus-per-task", "1", "--mem", "2G"]
        r = self.experiment(*submit)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("4 cells, 0 finished, 0 queued or running, 4 to submit", r.stderr)
        job = re.search(r"submitted Slurm array job (\d+)", r.stderr).group(1)
        with open(os.path.join(cluster, "submissions", "1.json")) as f:
            order = [cell_id(c) for c in json.load(f)["cells"]]
        self.assertEqual(order, [cell_id(c) for c in cells])

        # While it runs: a cell that has trained a while is cancelled.
        victim = None
        deadline = time.time() + 300
        while victim is None and time.time() < deadline:
            for index, state in self.cluster.tasks(job).items():
                metrics = os.path.join(cluster, "cells", order[index], "metrics.csv")
                if state == "RUNNING" and len(read_csv(metrics) if os.path.exists(metrics) else []) >= 3:
                    victim = index
                    break
            time.sleep(0.2)
        self.assertIsNotNone(victim, f"no task ran long enough to be cancelled\n{self.cluster.logs()}")
        run(["scancel", f"{job}_{victim}"], env=self.cluster.env).check_returncode()
        # While the array runs: --status names what runs, --report draws what is finished.
        r = self.experiment("--status", cluster)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertRegex(r.stdout, r"\b(running|pending)\s+job \d+_\d+ (running|pending)", r.stdout)
        r = self.experiment("--report", cluster)
        self.assertEqual(r.returncode, 0, r.stderr)
        deadline = time.time() + 600
        while self.cluster.tasks(job) and time.time() < deadline:
            time.sleep(0.5)
        self.assertFalse(self.cluster.tasks(job), "the array did not end")
        print(f"slurm: the array (one task cancelled) ended after {time.time() - t0:.0f} s", file=sys.stderr)

        r = self.experiment("--status", cluster)
        self.assertEqual(r.returncode, 0, r.stderr)
        print(f"slurm: --status after the array:\n{r.stdout}", file=sys.stderr)
        lines = {line.split()[0]: line for line in r.stdout.splitlines() if line.split()[0] in order}
        for index, cid in enumerate(order):
            if index == victim:
                self.assertRegex(lines[cid], rf"\bfailed\s+job {job}_{victim} CANCELLED: ", r.stdout)
            else:
                self.assertRegex(lines[cid], r"\bdone\s+success \d+%", r.stdout)
        self.assertIn("4 cells: 3 done, 1 failed", r.stdout)
        summaries = {cid: os.stat(os.path.join(cluster, "cells", cid, "summary.json")).st_mtime_ns
                     for i, cid in enumerate(order) if i != victim}

        # Resubmitted: only the cancelled cell runs again.
        t0 = time.time()
        r = self.experiment(*submit, "--wait", "--poll-seconds", "1")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("4 cells, 3 finished, 0 queued or running, 1 to submit", r.stderr)
        with open(os.path.join(cluster, "submissions", "2.json")) as f:
            self.assertEqual([cell_id(c) for c in json.load(f)["cells"]], [order[victim]])
        print(f"slurm: the resubmission (1 cell) ended after {time.time() - t0:.0f} s", file=sys.stderr)
        self.assertEqual(task_starts(cluster), {cid: 2 if i == victim else 1 for i, cid in enumerate(order)})
        for cid, mtime in summaries.items():
            self.assertEqual(os.stat(os.path.join(cluster, "cells", cid, "summary.json")).st_mtime_ns, mtime, cid)
        r = self.experiment("--status", cluster)
        self.assertIn("4 cells: 4 done", r.stdout)
        # Nothing is left to submit.
        r = self.experiment(*submit)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("4 cells, 4 finished, 0 queued or running, 0 to submit", r.stderr)
        self.assertFalse(os.path.exists(os.path.join(cluster, "submissions", "3.json")))

        # Deterministic cells: each run folder as the local one, byte for byte,
        # and so the same tables.
        for cid in order:
            rows, same = same_run.differences(os.path.join(local, "cells", cid), os.path.join(cluster, "cells", cid))
            self.assertTrue(same, (cid, rows))
        for name in ("table.csv", "stats.csv", "runs.csv"):
            self.assertEqual(read_csv(os.path.join(cluster, name), WALL_COLUMNS),
                             read_csv(os.path.join(local, name), WALL_COLUMNS), name)

        # A finished cell run with other settings (defaults changed since) is
        # not mixed in: the submission stops with one line naming the setting.
        config_path = os.path.join(cluster, "cells", order[0], "config.json")
        with open(config_path) as f:
            config = json.load(f)
        config["beta"] = config["beta"] * 2
        with open(config_path, "w") as f:
            json.dump(config, f)
        r = self.experiment(*submit)
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn(f"{order[0]} was run with beta", r.stderr)
        self.assertFalse(os.path.exists(os.path.join(cluster, "submissions", "3.json")))

    def test_refusals_are_one_line(self):
        grid = write_grid(self.tmp)
        out = os.path.join(self.tmp, "refused")
        r = self.experiment("--grid", grid, "--out", out, "--backend", "slurm", "--partition", "nosuch")
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertEqual(len(r.stderr.strip().splitlines()), 2, r.stderr)  # The plan line, then the refusal.
        self.assertIn("sbatch refused the array", r.stderr)
        self.assertFalse(os.listdir(os.path.join(out, "submissions")), "a refused array leaves no submission")
        r = self.experiment("--grid", grid, "--out", out, "--backend", "slurm", "--only", "nosuch-cell")
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("--only: 'nosuch-cell' is not a cell", r.stderr)


class SlurmScriptTest(unittest.TestCase):
    """The batch script, statically (SlurmTest runs it under a real Slurm)."""

    def test_the_submitters_kernels_reach_every_batch_script(self):
        with tempfile.TemporaryDirectory() as tmp:
            os.makedirs(cluster.submissions_dir(tmp))
            without = environment_without_kernels()
            for pinned in ({}, {"OPENBLAS_CORETYPE": "Haswell", "ATEN_CPU_CAPABILITY": "avx2"}):
                with unittest.mock.patch.dict(os.environ, dict(without, **pinned), clear=True):
                    with open(cluster.task_script(tmp, {"number": 1})) as f:
                        text = f.read()
                for name, value in (("OPENBLAS_CORETYPE", "Haswell"), ("ATEN_CPU_CAPABILITY", "avx2")):
                    self.assertEqual(f"export {name}={value}\n" in text, bool(pinned), text)


class KubernetesTest(unittest.TestCase):
    """--backend k8s: the manifest, statically, and the pod's command run here."""

    def manifest(self, out, *argv, grid=None, env=None):
        tmp = os.path.dirname(out)
        source = ["--grid", write_grid(tmp, grid)] if grid else ["--preset", "quick"]
        r = run(EXPERIMENT + source + ["--out", out, "--backend", "k8s", *argv], env=env)
        self.assertEqual(r.returncode, 0, r.stderr)
        found = re.search(r"wrote (\S+\.yaml)", r.stderr)
        if not found:
            return None
        with open(found.group(1)) as f:
            return list(yaml.safe_load_all(f))

    def test_quick_preset_is_one_indexed_job_whose_index_selects_the_cell(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "quick-v3")
            config_map, job = self.manifest(out, "--cpus-per-task", "2", "--mem", "3G", "--jobs", "8")
            cells = expand(presets.presets()["quick"]["entries"], "quick")
            self.assertEqual((config_map["kind"], job["kind"]), ("ConfigMap", "Job"))
            queue = json.loads(config_map["data"]["cells.json"])
            self.assertEqual(queue["cells"], json.loads(json.dumps(cells)))
            spec = job["spec"]
            self.assertEqual(spec["completionMode"], "Indexed")
            self.assertEqual((spec["completions"], spec["parallelism"]), (len(cells), 8))
            # One bad cell fails its index, not the grid.
            self.assertEqual(spec["backoffLimitPerIndex"], 1)
            self.assertEqual(spec["maxFailedIndexes"], len(cells))
            self.assertNotIn("backoffLimit", spec)
            self.assertIn({"action": "Ignore", "onPodConditions": [{"type": "DisruptionTarget", "status": "True"}]},
                          spec["podFailurePolicy"]["rules"])
            pod = spec["template"]["spec"]
            self.assertEqual(pod["restartPolicy"], "Never")  # podFailurePolicy and per-index backoff need it.
            # Long enough for ./imca train to stop its services in order.
            self.assertGreaterEqual(pod["terminationGracePeriodSeconds"], 270)
            (container,) = pod["containers"]
            self.assertEqual((container["image"], container["imagePullPolicy"]), ("imca:latest", "IfNotPresent"))
            self.assertEqual(container["resources"], {"requests": {"cpu": "2", "memory": "3Gi"},
                                                      "limits": {"memory": "3Gi"}})
            volumes = {v["name"]: v for v in pod["volumes"]}
            mounts = {m["mountPath"]: volumes[m["name"]] for m in container["volumeMounts"]}
            command = container["command"]
            self.assertEqual(command[:3], ["python3", "-m", "imca_tools.experiment"])
            queue_file = command[command.index("--run-cell") + 1]
            results = command[command.index("--out") + 1]
            self.assertEqual(results, "/results/quick-v3")
            self.assertEqual(mounts[os.path.dirname(queue_file)]["configMap"]["name"], config_map["metadata"]["name"])
            self.assertIn("cells.json", config_map["data"])
            claim = next(v for path, v in mounts.items() if results.startswith(path + "/"))
            self.assertEqual(claim["persistentVolumeClaim"]["claimName"], "imca-results")
            self.assertEqual(job["metadata"]["name"], config_map["metadata"]["name"])
            self.assertRegex(job["metadata"]["name"], r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$")
            # The image the deployment builds is the one the Job runs.
            with open(os.path.join(binaries.ROOT, "deploy", "k8s", "kustomization.yaml")) as f:
                (image,) = yaml.safe_load(f)["images"]
            self.assertEqual(f"{image['newName']}:{image['newTag']}", container["image"])

    def test_the_submitters_kernels_reach_every_pod(self):
        # Nodes of several CPU kinds would run cells on several kernels: the
        # ones the submitter pins reach every pod (docs/learner.md).
        with tempfile.TemporaryDirectory() as tmp:
            without = environment_without_kernels()
            _, job = self.manifest(os.path.join(tmp, "a"), env=without)
            (container,) = job["spec"]["template"]["spec"]["containers"]
            self.assertNotIn("env", container)
            _, job = self.manifest(os.path.join(tmp, "b"), env=dict(without, OPENBLAS_CORETYPE="Haswell",
                                                                    ATEN_CPU_CAPABILITY="avx2"))
            (container,) = job["spec"]["template"]["spec"]["containers"]
            self.assertEqual(container["env"], [{"name": "OPENBLAS_CORETYPE", "value": "Haswell"},
                                                {"name": "ATEN_CPU_CAPABILITY", "value": "avx2"}])

    def test_the_pods_command_runs_its_cell_and_a_second_manifest_holds_only_what_is_missing(self):
        grid = {"name": "pods", "entries": [{"scenario": "coop_nav", "reward": "count", "credit": ["shared", "imca"],
                                             "seed": 1, "steps": 16000, "flags": SMALL}]}
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "pods")
            config_map, job = self.manifest(out, grid=grid)
            # The pod's filesystem, here: the claim and the ConfigMap as folders.
            claim, queue = os.path.join(tmp, "claim"), os.path.join(tmp, "queue")
            os.makedirs(queue)
            for name, text in config_map["data"].items():
                with open(os.path.join(queue, name), "w") as f:
                    f.write(text)
            (container,) = job["spec"]["template"]["spec"]["containers"]
            mapped = [a.replace("/etc/imca/queue", queue).replace("/results", claim) for a in container["command"]]
            mapped[0] = sys.executable
            env = binaries.module_env(dict(os.environ, JOB_COMPLETION_INDEX="0"))
            r = run(mapped, env=env)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            cells = expand(grid["entries"], "test")
            first = os.path.join(claim, "pods", "cells", cell_id(cells[0]))
            self.assertTrue(runner.finished(first, cells[0]), r.stdout)
            # A retried pod of a finished cell leaves it as it is.
            r = run(mapped, env=env)
            self.assertEqual(r.returncode, 0, r.stdout)
            self.assertIn("already finished", r.stdout)
            # An index past the cells is a one-line error.
            r = run(mapped, env=dict(env, JOB_COMPLETION_INDEX="2"))
            self.assertEqual(r.returncode, 2)
            self.assertIn("index 2 is outside the submission's 2 cells", r.stderr)

            # The results copied back: the next manifest runs only the other cell.
            shutil.copytree(os.path.join(claim, "pods", "cells"), os.path.join(out, "cells"))
            config_map, job = self.manifest(out, grid=grid)
            self.assertEqual([cell_id(c) for c in json.loads(config_map["data"]["cells.json"])["cells"]],
                             [cell_id(cells[1])])
            self.assertEqual(job["spec"]["completions"], 1)
            self.assertTrue(job["metadata"]["name"].endswith("-2"))

    def test_flags_of_another_backend_are_one_line_errors(self):
        with tempfile.TemporaryDirectory() as tmp:
            grid = write_grid(tmp)
            for argv, words in ((["--backend", "k8s", "--wait"], "--wait: only with"),
                                (["--backend", "k8s", "--mem", "lots"], "--mem: 'lots' is not a size"),
                                (["--mem", "4G"], "--mem: only with"),
                                (["--backend", "slurm", "--apply"], "--apply: only with"),
                                (["--backend", "k8s", "--k8s-out", "/data/x"], "--k8s-out: must lie under /results/")):
                r = run(EXPERIMENT + ["--grid", grid, "--out", os.path.join(tmp, "out")] + argv)
                self.assertEqual(r.returncode, 2, (argv, r.stderr))
                self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
                self.assertFalse(os.path.exists(os.path.join(tmp, "out", "submissions")), argv)
                self.assertIn(words, r.stderr)
            r = run(EXPERIMENT + ["--report", tmp, "--backend", "slurm"])
            self.assertEqual(r.returncode, 2)
            self.assertIn("--backend: only with --preset or --grid", r.stderr)


if __name__ == "__main__":
    unittest.main(verbosity=2)
