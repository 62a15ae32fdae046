"""The process supervisor: the loopback stand-in for Compose's and
Kubernetes' restart policies (docs/reliability.md).

Services starts a run's processes, restarts the ones that die or stall (with
backoff, up to a cap), stops them in dependency order, and logs each
incarnation; run_processes finds a run's live processes by name.
"""
import ctypes
import os
import signal
import subprocess
import sys
import time

from . import binaries
from .runs import read_json

# The supervisor's own settings (./imca train --max-restarts, --stall-seconds;
# docs/reliability.md): how patient the stand-in for a restart policy is, not
# how anything trains.
MAX_RESTARTS = 5
STALL_SECONDS = 60.0

def _die_with_parent():
    """In the child before exec: SIGTERM when the launcher dies, even by kill -9
    (so that no child outlives it), and a new session, so that the terminal's
    Ctrl-C reaches only the launcher, which then stops the children in order."""
    os.setsid()
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except OSError:
        pass


class Services:
    """The child processes of one run, supervised and stopped in dependency order.

    A child that dies (any exit but a finished one) is started again with the
    same argv plus `restart_args`, after a backoff of 1 s doubling to 30 s;
    past `max_restarts` restarts of one process the run ends with one line
    naming it and its last log line. A child whose status file (written every
    second by each binary) goes quiet for `stall_seconds`, or whose own
    status says it is stalled, is killed and restarted the same way. Each
    incarnation logs to logs/<name>.log, logs/<name>.1.log, ...; every restart
    is a row of logs/restarts.csv.
    """

    def __init__(self, run_dir, max_restarts=MAX_RESTARTS, stall_seconds=STALL_SECONDS):
        self.run_dir = run_dir
        self.logs = os.path.join(run_dir, "logs")
        os.makedirs(self.logs, exist_ok=True)
        self.max_restarts = max_restarts
        self.stall_seconds = stall_seconds
        self.procs = []  # [name, Popen], in start order.
        self.argv = {}
        self.restart_args = {}
        self.restarts = {}
        self.started = {}
        self.pending = {}  # name -> time at which to start it again.
        self.log_names = {}
        self.finished_codes = {}
        self._learner_steps, self._learner_moved = None, time.time()  # check_deadlock's.

    def status_file(self, name):
        return os.path.join(self.logs, name + ".status.json")

    def log_path(self, name):
        return os.path.join(self.logs, self.log_names.get(name, name + ".log"))

    def start(self, name, argv, restart_args=None, finished_codes=(0,)):
        self.argv[name] = list(argv)
        self.restart_args[name] = restart_args or (lambda: [])
        self.restarts.setdefault(name, 0)
        self.finished_codes[name] = finished_codes
        return self._spawn(name, list(argv) + [f"--status_file={self.status_file(name)}"])

    def _spawn(self, name, argv):
        k = self.restarts[name]
        self.log_names[name] = f"{name}.log" if k == 0 else f"{name}.{k}.log"
        try:
            os.remove(self.status_file(name))
        except OSError:
            pass
        log = open(self.log_path(name), "ab")
        proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, preexec_fn=_die_with_parent)
        log.close()
        for entry in self.procs:
            if entry[0] == name:
                entry[1] = proc
                break
        else:
            self.procs.append([name, proc])
        self.started[name] = time.time()
        return proc

    def proc(self, name):
        return next(p for n, p in self.procs if n == name)

    def last_log_line(self, name):
        try:
            with open(self.log_path(name), errors="replace") as f:
                lines = [l.strip() for l in f if l.strip()]
            return lines[-1] if lines else f"{name} exited"
        except OSError:
            return f"{name} exited"

    def newest_log_line(self):
        """(process, its log's last line) of the log written last, or None:
        what a run that makes no progress last said (a disk full, a refused
        connection)."""
        newest = None
        for name, _ in self.procs:
            try:
                mtime = os.path.getmtime(self.log_path(name))
            except OSError:
                continue
            if newest is None or mtime > newest[0]:
                newest = (mtime, name)
        return None if newest is None else (newest[1], self.last_log_line(newest[1]))

    def wait_port(self, name, proc, port_file, timeout=30.0):
        deadline = time.time() + timeout
        while time.time() < deadline:
            if proc.poll() is not None:
                raise binaries.LaunchError(self.last_log_line(name))
            try:
                with open(port_file) as f:
                    text = f.read().strip()
                if text:
                    return int(text)
            except OSError:
                pass
            time.sleep(0.05)
        raise binaries.LaunchError(f"{name} did not start serving within {timeout:.0f} s")

    def _stalled(self, name, now):
        """Why `name` counts as stalled, or None."""
        status = read_json(self.status_file(name))
        if status is None or "time" not in status:
            # Starting up (a reward server replaying a long journal, a learner
            # loading a checkpoint) gets a longer grace before its first status.
            if now - self.started[name] > 2 * self.stall_seconds + 60:
                return f"no status {now - self.started[name]:.0f} s after its start"
            return None
        quiet = now - max(status["time"], self.started[name])
        if quiet > self.stall_seconds:
            return f"no status for {quiet:.0f} s"
        if status.get("seconds_stalled", 0) > self.stall_seconds:
            return f"unrolls waited {status['seconds_stalled']:.0f} s without training"
        if status.get("seconds_training", 0) > 10 * self.stall_seconds:
            return f"one PPO update has run for {status['seconds_training']:.0f} s"
        return None

    def _record(self, name, reason):
        path = os.path.join(self.logs, "restarts.csv")
        fresh = not os.path.exists(path)
        with open(path, "a") as f:
            if fresh:
                f.write("time,process,restart,reason\n")
            f.write(f"{time.time():.3f},{name},{self.restarts[name]},\"{reason}\"\n")

    def supervise(self, names):
        """Restarts what died or stalled among `names`; raises past the cap.
        Returns the names that finished (exited with a finished code)."""
        now = time.time()
        finished = []
        for name in names:
            if name in self.pending:
                if now >= self.pending[name]:
                    del self.pending[name]
                    self._spawn(name, self.argv[name] + self.restart_args[name]()
                                + [f"--status_file={self.status_file(name)}"])
                continue
            proc = self.proc(name)
            code = proc.poll()
            if code is not None and code in self.finished_codes[name]:
                finished.append(name)
                continue
            if code == binaries.exit_refused():
                # A server refused its credentials: the same ones would be
                # refused again, so no restart.
                raise binaries.LaunchError(f"{name} was refused by a server (exit {code}): {self.last_log_line(name)}")
            if code == binaries.exit_misconfigured():
                # Its configuration cannot work with its peers: neither can a restart's.
                raise binaries.LaunchError(f"{name} cannot work with its peers (exit {code}): {self.last_log_line(name)}")
            reason = None
            if code is not None:
                reason = f"exited with code {code}"
            else:
                stalled = self._stalled(name, now)
                if stalled:
                    reason = f"made no progress ({stalled})"
                    proc.kill()
                    proc.wait()
            if reason is None:
                continue
            last = self.last_log_line(name)
            if self.restarts[name] >= self.max_restarts:
                raise binaries.LaunchError(f"{name} {reason}, {self.restarts[name]} restarts already (--max-restarts): {last}")
            delay = min(30.0, 2.0 ** self.restarts[name])
            self.restarts[name] += 1
            self._record(name, f"{reason}: {last}".replace('"', "'"))
            print(f"\nimca train: {name} {reason} ({last}); restart {self.restarts[name]} in {delay:.0f} s",
                  file=sys.stderr, flush=True)
            self.pending[name] = now + delay
        return finished

    def check_deadlock(self, learner, actors):
        """A net under protocol bugs: the learner has not trained for twice
        stall_seconds while every actor waits for a policy (each side waits
        for the other). Kills the actors, which supervise() then restarts:
        a fresh actor acts with whatever policy the learner has."""
        now = time.time()
        status = read_json(self.status_file(learner)) or {}
        steps = status.get("env_steps")
        if steps != self._learner_steps or learner in self.pending or status.get("seconds_training", 0) > 0:
            self._learner_steps, self._learner_moved = steps, now
            return
        # Twice the stall limit, and only with every actor alive and saying
        # so: a silent actor is the stall detector's to restart, first.
        if now - self._learner_moved < 2 * self.stall_seconds or any(a in self.pending for a in actors):
            return
        statuses = [read_json(self.status_file(a)) or {} for a in actors]
        if statuses and all(st.get("state") == "WAITING_POLICY" and now - st.get("time", 0) < self.stall_seconds / 2
                            for st in statuses):
            print(f"\nimca train: the learner has not trained for {now - self._learner_moved:.0f} s while every "
                  "actor waits for a policy; restarting the actors", file=sys.stderr, flush=True)
            for a in actors:
                self.proc(a).kill()
            self._learner_moved = now

    def total_restarts(self):
        return sum(self.restarts.values())

    def stop(self, names=None, timeout=30.0):
        """SIGTERM to all of `names` at once, then wait; returns {name: exit code}."""
        codes = {}
        for name in list(self.pending):
            if names is None or name in names:
                del self.pending[name]  # Never started again.
        chosen = [(n, p) for n, p in self.procs if names is None or n in names]
        for name, proc in chosen:
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        for name, proc in chosen:
            try:
                codes[name] = proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                codes[name] = proc.wait()
        return codes


def run_processes(run_dir):
    """{name: pid} of the live processes of a run (by the run folder in their argv)."""
    found = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/cmdline", "rb") as f:
                argv = f.read().decode(errors="replace").split("\0")
            with open(f"/proc/{entry}/stat") as f:
                if f.read().split(") ")[-1].startswith("Z"):
                    continue  # A zombie: dead, not yet reaped.
        except OSError:
            continue
        binary = os.path.basename(argv[0])
        if binary not in binaries.PROGRAMS or not any(run_dir in a for a in argv):
            continue
        name = binary
        for a in argv:
            if a.startswith("--actor_id="):
                name = a.split("=", 1)[1]
        found[name] = int(entry)
    return found
