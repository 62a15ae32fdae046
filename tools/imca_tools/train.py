"""./imca train: one reward server, one learner and N actors on loopback.

Starts the three services as separate processes on free ports, shows a live
progress line, and leaves a run folder (docs/usage.md, "What a run leaves").
Ctrl-C stops every process in order (actors, learner, reward server) and still
leaves a valid run folder.
"""
import datetime
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time

from . import binaries, runs
from .binaries import BIN, LaunchError
from .plan import parse_args, plan
from .supervisor import Services


# A run that adds no metrics row for this long, or for three of its own
# iterations if those are longer, says why on its progress line.
QUIET_NOTE_SECONDS = 30


def progress_line(row, budget, restarts=0, quiet=None):
    """The live line of a run from its newest metrics row (None: none yet);
    `quiet`, (seconds without a new row, (process, last log line) or None),
    when the run has gone quiet (quiet_since)."""
    note = ""
    if quiet is not None:
        seconds, said = quiet
        note = f"no new iteration for {runs.fmt_duration(seconds)}"
        if said is not None:
            note += f": {said[0]} says {said[1]}"
    if row is None:
        return "starting" + (f" | {note}" if note else "")
    steps = int(row["env_steps"])
    rate = float(row["env_steps_per_sec"])
    eta = (budget - steps) / rate if rate > 0 else 0
    return (f"steps {steps:,}/{budget:,} | {rate:,.0f} steps/s | success {float(row['success_rate']):.1%}"
            f" | return {float(row['episode_return']):.2f} | intrinsic {float(row['intrinsic_reward']):.4f}"
            f" | ETA {runs.fmt_duration(eta)}" + (f" | restarts {restarts}" if restarts else "")
            + (f" | {note}" if note else ""))


def quiet_since(rows, last_change, now):
    """Seconds the run has added no row, if that is long enough to say so
    (QUIET_NOTE_SECONDS, or three of its last iterations), else None."""
    interval = 0.0
    if len(rows) >= 2:
        interval = float(rows[-1]["wall_seconds"]) - float(rows[-2]["wall_seconds"])
    quiet = now - last_change
    return quiet if quiet > max(QUIET_NOTE_SECONDS, 3 * interval) else None


def plot(run_dir, rows, title):
    # matplotlib is heavy: imported once a run has something to draw.
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    steps = [int(r["env_steps"]) for r in rows]
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    series = [("success_rate", "evaluation success rate"), ("episode_return", "episode return (team)"),
              ("intrinsic_reward", "mean intrinsic reward / agent-step")]
    for ax, (key, label) in zip(axes, series):
        ax.plot(steps, [float(r[key]) for r in rows], lw=1.5)
        ax.set_xlabel("env steps")
        ax.set_title(label, fontsize=10)
        ax.grid(alpha=0.3)
    axes[0].set_ylim(-0.02, 1.02)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    fig.savefig(os.path.join(run_dir, "learning_curve.png"), dpi=110)
    plt.close(fig)


# The programs a run executes.
RUN_PROGRAMS = binaries.PROGRAMS + ("imca_env",)


def binary_digests(directory):
    """{program: sha256} of the run's programs in `directory`."""
    digests = {}
    for program in RUN_PROGRAMS:
        try:
            with open(os.path.join(directory, program), "rb") as f:
                digests[program] = hashlib.file_digest(f, "sha256").hexdigest()
        except OSError as error:
            raise LaunchError(f"cannot read {os.path.join(directory, program)} ({error.strerror}); "
                              "build first: ./imca build") from None
    return digests


def pin_binaries(run_dir, expected):
    """Copies the run's programs from BIN into RUN/bin and returns RUN/bin:
    the run starts, and the supervisor restarts, every service from there,
    so a build that relinks build/bin while the run goes on changes nothing
    in it. `expected` ({program: sha256}, taken before the binaries checked
    the run's flags) must be what was copied: else build/bin changed
    meanwhile and LaunchError says so. On a run folder that cannot hold
    programs (a noexec mount) the run executes BIN itself, with a warning.
    RUN/bin goes when the run ends (train.run); a launcher killed by
    SIGKILL leaves it, and the next start replaces it."""
    pinned = os.path.join(run_dir, "bin")
    try:
        os.makedirs(pinned, exist_ok=True)
        for program in RUN_PROGRAMS:
            target = os.path.join(pinned, program)
            shutil.copy2(os.path.join(BIN, program), target + ".tmp")
            os.replace(target + ".tmp", target)
        if binary_digests(pinned) != expected:
            raise LaunchError(f"{BIN} changed while the run started (a build running?); start it again")
        if not os.access(os.path.join(pinned, "learner"), os.X_OK):
            shutil.rmtree(pinned, ignore_errors=True)
            print(f"imca train: {run_dir} cannot hold programs (a noexec mount?): the run executes {BIN}, and a "
                  "rebuild during the run would reach its restarts", file=sys.stderr)
            return BIN
        return pinned
    except BaseException as error:
        shutil.rmtree(pinned, ignore_errors=True)
        if isinstance(error, OSError):
            raise LaunchError(f"cannot copy the binaries into {pinned}: {error.strerror}") from None
        raise


def unpin_binaries(bin_dir):
    """Removes a run's copy of the binaries (pin_binaries' RUN/bin; never BIN)."""
    if bin_dir != BIN:
        shutil.rmtree(bin_dir, ignore_errors=True)


def builds_before(run_dir, built):
    """A resumed run's earlier builds ({program: sha256} each, oldest first)
    other than `built`: config.json's binaries_earlier, and its binaries if
    they differ (a run resumed on another build ran two)."""
    saved = runs.read_json(os.path.join(run_dir, "config.json")) or {}
    earlier = list(saved.get("binaries_earlier") or [])
    if saved.get("binaries") and saved["binaries"] != built:
        earlier.append(saved["binaries"])
    return earlier


def episode_gif(bin_dir, run_dir, scenario_flags, seed):
    """One episode of the final policy as episode.gif (best effort: a run
    stopped before its first checkpoint has no policy.pb)."""
    policy = os.path.join(run_dir, "policy.pb")
    if not os.path.exists(policy):
        return
    r = subprocess.run([os.path.join(bin_dir, "imca_env"), "rollout", *scenario_flags, f"--policy={policy}",
                        f"--seed={seed}", "--json", f"--gif={os.path.join(run_dir, 'episode.gif')}"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        print(f"imca train: no episode.gif: {r.stderr.strip()}", file=sys.stderr)


def secure_flags(run_dir, args):
    """Makes (or, on resume, reuses) the run's CA, certificates and token in
    <run_dir>/tls; returns the servers' flags and a function of the actor
    index giving its flags (its own client certificate, CN=actor-<i>)."""
    tls = os.path.join(run_dir, "tls")
    clients = [f"actor-{i}" for i in range(args.actors)]
    if not all(os.path.exists(os.path.join(tls, f"{c}.pem")) for c in clients + ["ca", "server"]):
        r = subprocess.run([binaries.MAKE_CERTS, tls] + clients,
                           capture_output=True, text=True)
        if r.returncode != 0:
            raise LaunchError(f"--secure: making certificates with openssl failed: {r.stderr.strip()}")
    path = lambda name: os.path.join(tls, name)
    server = [f"--tls_cert={path('server.pem')}", f"--tls_key={path('server.key')}", f"--tls_ca={path('ca.pem')}",
              "--tls_client_auth=true", f"--token_file={path('token')}"]
    actor = lambda i: [f"--tls_ca={path('ca.pem')}", f"--tls_cert={path(f'actor-{i}.pem')}",
                       f"--tls_key={path(f'actor-{i}.key')}", f"--token_file={path('token')}"]
    return server, actor


def metrics_ports(args):
    """--metrics-port's port of each process (an empty dict without it)."""
    if not args.metrics_port:
        return {}
    ports = {"reward_server": args.metrics_port, "learner": args.metrics_port + 1}
    for i in range(args.actors):
        ports[f"actor-{i}"] = args.metrics_port + 2 + i
    return ports


def write_prometheus_config(run_dir, ports, scrape_interval="5s"):
    """<run_dir>/prometheus.yml: a Prometheus configuration that scrapes the
    run's endpoints (jobs reward_server, learner, actor) with the alert and
    recording rules of deploy/prometheus/."""
    jobs = {}
    for name, port in ports.items():
        jobs.setdefault(name.split("-")[0], []).append(f"127.0.0.1:{port}")
    lines = ["# Written by ./imca train --metrics-port: prometheus --config.file=<this file>",
             "global:", f"  scrape_interval: {scrape_interval}", f"  evaluation_interval: {scrape_interval}",
             "rule_files:", f"  - {json.dumps(os.path.join(binaries.ROOT, 'deploy', 'prometheus', 'rules.yml'))}",
             "scrape_configs:"]
    for job, targets in jobs.items():
        lines += [f"  - job_name: {job}", "    static_configs:",
                  "      - targets: [" + ", ".join(json.dumps(t) for t in targets) + "]"]
    with open(os.path.join(run_dir, "prometheus.yml"), "w") as f:
        f.write("\n".join(lines) + "\n")



def run(args):
    run_dir = args.out or os.path.join("runs", datetime.datetime.now().strftime("%Y%m%d-%H%M%S"))
    run_dir = os.path.abspath(run_dir)
    if os.path.exists(os.path.join(run_dir, "metrics.csv")) and not args.resume:
        raise LaunchError(f"--out: '{run_dir}' already holds a run (use --resume to continue it)")
    built = binary_digests(BIN)  # The build whose binaries check the flags.
    flags, config = plan(args)  # Nothing is made or started for a configuration the binaries refuse.
    os.makedirs(run_dir, exist_ok=True)
    bin_dir = pin_binaries(run_dir, built)
    try:
        config["binaries"] = built
        earlier = builds_before(run_dir, built) if args.resume else []
        if earlier:
            config["binaries_earlier"] = earlier
        runs.write_json_atomically(os.path.join(run_dir, "config.json"), config)
        scenario_flags = flags["imca_env"]
        server_tls, actor_tls = secure_flags(run_dir, args) if args.secure else ([], lambda i: [])
        ports = metrics_ports(args)
        metrics_flag = lambda name: [f"--metrics_listen=127.0.0.1:{ports[name]}"] if ports else []
        if ports:
            write_prometheus_config(run_dir, ports)
        services = Services(run_dir, max_restarts=args.max_restarts, stall_seconds=args.stall_seconds)
    except BaseException:
        unpin_binaries(bin_dir)
        raise
    rows = []
    interrupted = False
    stop_requested = []
    signal.signal(signal.SIGTERM, lambda *_: stop_requested.append(1))
    try:
        reward_port_file = os.path.join(run_dir, "logs", "reward_server.port")
        learner_port_file = os.path.join(run_dir, "logs", "learner.port")
        for path in (reward_port_file, learner_port_file):
            if os.path.exists(path):
                os.remove(path)
        # A restarted server comes back on the port it had (its clients
        # reconnect there) and from its saved state.
        reward_port = []
        rs = services.start("reward_server", [
            os.path.join(bin_dir, "reward_server"), f"--port_file={reward_port_file}", *flags["reward_server"],
            f"--snapshot={os.path.join(run_dir, 'reward_snapshot.bin')}", *server_tls, *metrics_flag("reward_server"),
            f"--listen=127.0.0.1:{args.reward_port}"],
            restart_args=lambda: [f"--listen=127.0.0.1:{reward_port[0]}"],
            finished_codes=())  # It never finishes by itself: any exit is a death.
        reward_port.append(services.wait_port("reward_server", rs, reward_port_file))
        learner_port = []
        ln = services.start("learner", [
            os.path.join(bin_dir, "learner"), f"--port_file={learner_port_file}", *flags["learner"],
            f"--run_dir={run_dir}", f"--trained_log={os.path.join(run_dir, 'logs', 'trained_unrolls.csv')}",
            # Stopped by a signal it did not get from us (exit 143, not 0):
            # restarted, not taken for finished.
            "--signal_exit_code=143"]
            + ([f"--resume={os.path.join(run_dir, 'checkpoints')}"] if args.resume else [])
            + server_tls + metrics_flag("learner") + [f"--listen=127.0.0.1:{args.learner_port}"],
            # From its newest checkpoint (none yet: from scratch).
            restart_args=lambda: [f"--listen=127.0.0.1:{learner_port[0]}", "--resume=", "--auto_resume=true"])
        learner_port.append(services.wait_port("learner", ln, learner_port_file, timeout=60))
        actors = []
        for i in range(args.actors):
            name = f"actor-{i}"
            actors.append(name)
            # A restarted actor (same id, new incarnation) draws other
            # episodes than the dead one: its seed moves with the restart.
            services.start(name, [
                os.path.join(bin_dir, "actor"), f"--learner=127.0.0.1:{learner_port[0]}",
                f"--reward_server=127.0.0.1:{reward_port[0]}", *flags["actor"],
                f"--actor_id={name}", "--signal_exit_code=143",
                # Its own wait for an ack gives up before the supervisor's.
                f"--ack_timeout_ms={int(args.stall_seconds * 500)}"] + actor_tls(i) + metrics_flag(name)
                + ([f"--trace_file={os.path.join(run_dir, 'credit_trace.csv')}"] if i == 0 else [])
                + ([f"--score_delay_ms={args.score_delays[i]}"] if i < len(args.score_delays) else [])
                + [f"--seed={args.seed * 1000 + i + 1}"],
                restart_args=lambda name=name, i=i: [
                    f"--seed={args.seed * 1000 + i + 1 + 1_000_003 * services.restarts[name]}"])
        tty = sys.stderr.isatty()
        last_print = 0.0
        last_rows, last_change = 0, time.time()
        learner_done = False
        while not learner_done:
            if stop_requested:
                raise KeyboardInterrupt
            time.sleep(0.5)
            # The learner exits 0 only with its budget trained; actors exit
            # 0 once it is done.
            learner_done = "learner" in services.supervise(["reward_server", "learner"] + actors)
            services.check_deadlock("learner", actors)
            rows = runs.read_metrics(os.path.join(run_dir, "metrics.csv"))
            if len(rows) != last_rows:
                last_rows, last_change = len(rows), time.time()
            quiet = quiet_since(rows, last_change, time.time())
            if (rows or quiet) and not args.quiet and (tty or time.time() - last_print > 10):
                line = progress_line(rows[-1] if rows else None, args.steps, services.total_restarts(),
                                     (quiet, services.newest_log_line()) if quiet else None)
                print(("\r" + line + "\033[K") if tty else line, end="" if tty else "\n",
                      file=sys.stderr, flush=True)
                last_print = time.time()
    except KeyboardInterrupt:
        interrupted = True
        print("\nimca train: stopping (actors, learner, reward server)...", file=sys.stderr)
    finally:
        # A second Ctrl-C (or a hang-up) must not abandon the children mid-stop.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
        codes = services.stop(names=[n for n, _ in services.procs if n.startswith("actor-")])
        codes.update(services.stop(names=["learner"], timeout=120))
        codes.update(services.stop(names=["reward_server"], timeout=120))
        runs.write_json_atomically(os.path.join(run_dir, "logs", "exit_codes.json"), codes)
        config["restarts"] = dict(services.restarts)
        rows = runs.read_metrics(os.path.join(run_dir, "metrics.csv"))
        # summary.json comes last: its presence means the run folder is complete
        # (./imca experiment counts a cell as finished by it).
        try:
            if rows:
                plot(run_dir, rows, f"{args.scenario} / {args.reward} / credit={args.credit} / "
                                    f"permutation={args.permutation} / seed={args.seed}")
            episode_gif(bin_dir, run_dir, scenario_flags, args.seed)
        finally:
            unpin_binaries(bin_dir)
            runs.write_summary(run_dir, config, rows, interrupted)
    if not args.quiet:
        print(file=sys.stderr)
    with open(os.path.join(run_dir, "summary.json")) as f:
        summary = json.load(f)
    print(f"imca train: {summary['env_steps']:,} env steps in {summary['wall_seconds']:.0f} s "
          f"({summary['env_steps_per_sec']:,.0f}/s), final success rate {summary['final_success_rate']:.1%}; "
          f"run folder {run_dir}")
    return 130 if interrupted else 0


def main(argv=None):
    try:
        return run(parse_args(sys.argv[1:] if argv is None else argv, description=__doc__))
    except LaunchError as error:
        print(f"imca train: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
