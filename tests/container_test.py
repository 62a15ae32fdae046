"""./imca deploy-test: the image, deploy/docker-compose.yml and the reward
server's Kubernetes Deployment run for real, under podman.

  ./imca deploy-test                  prebuilt image (the host's build/bin), compose, kube play
  ./imca deploy-test --from-source    the image from deploy/Dockerfile (compiles: ~15-20 min on 2 cores)
  ./imca deploy-test compose|kube|image|experiment   one part only (image: build and scan it)

What it does: installs the deploy packages (deploy/packages.txt), points
podman at deploy/containers.conf (runc, ulimits this machine allows), makes a
debian:12 base with debootstrap if there is none (no registry answers here;
the tarball is cached in ~/.cache/imca), builds the imca and Prometheus
images, makes certificates (tools/make_certs.sh runs/compose/tls), and runs
the compose file through docker-compose against `podman system service`
with its 2 actors and a budget of --steps (the learner's default). It checks and prints: env steps to 90%
evaluation success (<= 1M), every Prometheus target up and the scraped
env-step rate against metrics.csv's, kill -9 of the learner and then of the
reward server (each restarted by compose and resumed, the reward server
with every answered count), the budget reached, the exit codes at
`docker-compose down` (docs/deploy.md), no keys or results in the image, and
(kube) the reward server's Deployment under `podman kube play`: the pod
starts, serves mutual TLS, its probe passes; and (experiment) the pod
command of ./imca experiment --backend k8s trains a small cell in the image.
Everything it started is torn
down, also on failure; images stay (the next run reuses them). Exit 1 if a
check fails.
"""
import argparse
import contextlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.parse
import urllib.request

import yaml

from imca_tools import binaries, cluster, grid, options, plan, runner, runs
from imca_tools.binaries import BIN, ROOT

DEPLOY = os.path.join(ROOT, "deploy")
COMPOSE = os.path.join(DEPLOY, "docker-compose.yml")
RUNS = os.path.join(ROOT, "runs", "compose")  # where the compose file mounts /runs and the secrets
TLS = os.path.join(RUNS, "tls")
CACHE = os.environ.get("IMCA_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "imca"))
BASE = "docker.io/library/debian:12"  # what `FROM debian:12` resolves to (registries.conf.d/shortnames.conf)
IMAGE = "localhost/imca:latest"
PROMETHEUS_IMAGE = "localhost/imca-prometheus:latest"
PROJECT = "imcadeploytest"
IMAGE_BINARIES = ("reward_server", "learner", "actor", "imca_env", "imca_health")
# The image's apt sources are the host's: the archive this machine installs from.
HOST_SOURCES = "/etc/apt/sources.list.d/debian.sources"


def host_sources():
    """(the host's Debian archive URI, its deb822 sources text) for debootstrap
    and the base image's apt."""
    with open(HOST_SOURCES) as f:
        text = f.read()
    uri = re.search(r"^URIs:\s*(\S+)", text, re.M)
    if not uri:
        raise RuntimeError(f"{HOST_SOURCES} names no archive (URIs:)")
    return uri.group(1), text


def say(text):
    print(f"deploy-test: {text}", file=sys.stderr, flush=True)


def run(argv, check=True, quiet=False, **kw):
    """Runs argv; its output captured (text). Raises on failure if check."""
    if not quiet:
        say("$ " + " ".join(argv))
    r = subprocess.run(argv, capture_output=True, text=True, **kw)
    if check and r.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} exited {r.returncode}:\n{r.stdout[-3000:]}{r.stderr[-3000:]}")
    return r


def podman(*args, check=True, quiet=True, **kw):
    return run(["podman", *args], check=check, quiet=quiet, **kw)


class Figures:
    """The checks' figures, one table row each."""

    def __init__(self):
        self.rows = []

    def add(self, what, value, limit, ok):
        self.rows.append((what, str(value), str(limit), bool(ok)))
        say(f"{'ok  ' if ok else 'FAIL'} {what}: {value} ({limit})")
        return ok

    def failed(self):
        return [r for r in self.rows if not r[3]]

    def table(self):
        lines = ["| check | measured | wanted | |", "|---|---|---|---|"]
        lines += [f"| {w} | {v} | {lim} | {'ok' if ok else 'FAIL'} |" for w, v, lim, ok in self.rows]
        return "\n".join(lines)


# ---------------------------------------------------------------- the engine

def setup_engine():
    subprocess.run([os.path.join(ROOT, "imca"), "packages", "deploy"], check=True)
    os.environ["CONTAINERS_CONF"] = os.path.join(DEPLOY, "containers.conf")


def make_base():
    """debian:12 for the Dockerfiles' FROM: debootstrap (minbase, from the
    host's archive and with its sources) imported once; the tarball is cached."""
    if podman("image", "exists", BASE, check=False).returncode == 0:
        return "present"
    os.makedirs(CACHE, exist_ok=True)
    tarball = os.path.join(CACHE, "debian-12.tar")
    made = "imported from the cached tarball"
    if not os.path.exists(tarball):
        rootfs = tempfile.mkdtemp(prefix="debian-12-", dir=CACHE)
        try:
            mirror, sources = host_sources()
            run(["debootstrap", "--variant=minbase", "bookworm", rootfs, mirror])
            os.remove(os.path.join(rootfs, "etc", "apt", "sources.list"))
            with open(os.path.join(rootfs, "etc", "apt", "sources.list.d", "debian.sources"), "w") as f:
                f.write(sources)
            run(["sh", "-c", f"rm -rf {rootfs}/var/cache/apt/archives/*.deb {rootfs}/var/lib/apt/lists/*"])
            run(["tar", "--numeric-owner", "-C", rootfs, "-cf", tarball + ".tmp", "."])
            os.replace(tarball + ".tmp", tarball)
        finally:
            shutil.rmtree(rootfs, ignore_errors=True)
        made = "made by debootstrap"
    podman("import", "--change", 'CMD ["bash"]', tarball, BASE, quiet=False)
    return made


def runtime_stage(dockerfile):
    """deploy/Dockerfile's runtime stage, as written (from its FROM to the end)."""
    text = open(dockerfile).read()
    start = re.search(r"^FROM \S+ AS runtime$", text, re.M)
    assert start, f"{dockerfile}: no runtime stage"
    return text[start.start():]


def build_image(from_source):
    """The imca image: deploy/Dockerfile as it is, or its runtime stage over a
    stage `build` holding the host's build/bin (seconds, not a compile)."""
    started = time.time()
    if from_source:
        run(["podman", "build", "-f", os.path.join(DEPLOY, "Dockerfile"), "-t", IMAGE, ROOT])
        return time.time() - started
    missing = [b for b in IMAGE_BINARIES if not os.path.exists(os.path.join(BIN, b))]
    if missing:
        raise RuntimeError(f"no {', '.join(missing)} in {BIN}: ./imca build first (or --from-source)")
    with tempfile.TemporaryDirectory(prefix="imca-context-") as ctx:
        os.makedirs(os.path.join(ctx, "bin"))
        for b in IMAGE_BINARIES:
            shutil.copy2(os.path.join(BIN, b), os.path.join(ctx, "bin", b))
        os.makedirs(os.path.join(ctx, "deploy"))
        shutil.copy2(os.path.join(DEPLOY, "packages.txt"), os.path.join(ctx, "deploy"))
        shutil.copytree(os.path.join(ROOT, "maps"), os.path.join(ctx, "maps"))
        shutil.copytree(os.path.join(ROOT, "tools", "imca_tools"), os.path.join(ctx, "tools", "imca_tools"),
                        ignore=shutil.ignore_patterns("__pycache__"))
        with open(os.path.join(ctx, "Dockerfile"), "w") as f:
            f.write("# ./imca deploy-test --prebuilt: the host's build/bin as stage build.\n"
                    "FROM scratch AS build\nCOPY bin/ /src/build/bin/\n\n" + runtime_stage(
                        os.path.join(DEPLOY, "Dockerfile")))
        run(["podman", "build", "-t", IMAGE, ctx])
    return time.time() - started


def build_prometheus():
    started = time.time()
    run(["podman", "build", "-f", os.path.join(DEPLOY, "prometheus", "Dockerfile"), "-t", PROMETHEUS_IMAGE, DEPLOY])
    return time.time() - started


def make_certs():
    """Fresh certificates where compose reads them (and the probe's, for kube)."""
    shutil.rmtree(TLS, ignore_errors=True)
    run([binaries.MAKE_CERTS, TLS, "actor", "probe"])


@contextlib.contextmanager
def podman_service():
    """`podman system service` on a private socket: docker-compose's engine."""
    tmp = tempfile.mkdtemp(prefix="imca-podman-")
    sock = os.path.join(tmp, "podman.sock")
    log = open(os.path.join(tmp, "service.log"), "w")
    proc = subprocess.Popen(["podman", "system", "service", "--time=0", f"unix://{sock}"], stdout=log,
                            stderr=subprocess.STDOUT)
    try:
        deadline = time.time() + 30
        while not os.path.exists(sock):
            if proc.poll() is not None or time.time() > deadline:
                raise RuntimeError("podman system service did not start: " + open(log.name).read())
            time.sleep(0.1)
        say(f"podman system service on {sock} (pid {proc.pid})")
        yield f"unix://{sock}"
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        log.close()
        shutil.rmtree(tmp, ignore_errors=True)


# ------------------------------------------------------------------ compose

def compose_actors():
    """The compose file's actor replicas: what its learner's --actors expects."""
    with open(COMPOSE) as f:
        return yaml.safe_load(f)["services"]["actor"]["deploy"]["replicas"]


def learner_default_steps():
    """The learner binary's default budget (what the compose file trains)."""
    return binaries.print_config("learner", [])["steps"]


class Compose:
    """docker-compose of deploy/docker-compose.yml as it is; another budget
    than the learner's default comes in an override file that appends
    --steps to the learner's command, as a user would."""

    def __init__(self, docker_host, steps):
        self.env = dict(os.environ, DOCKER_HOST=docker_host, COMPOSE_PROJECT_NAME=PROJECT)
        self.files = ["-f", COMPOSE]
        if steps != learner_default_steps():
            with open(COMPOSE) as f:
                command = yaml.safe_load(f)["services"]["learner"]["command"]
            override = os.path.join(tempfile.mkdtemp(prefix="imca-compose-"), "budget.yml")
            with open(override, "w") as f:
                yaml.safe_dump({"version": "3.8", "services": {"learner": {"command": command + [f"--steps={steps}"]}}},
                               f)
            self.files += ["-f", override]
        self.started = False

    def __call__(self, *args, check=True, timeout=600):
        say("$ docker-compose " + " ".join(args))
        r = subprocess.run(["docker-compose", *self.files, *args], env=self.env, capture_output=True, text=True,
                           timeout=timeout)
        if check and r.returncode != 0:
            raise RuntimeError(f"docker-compose {' '.join(args)} exited {r.returncode}:\n{r.stdout}{r.stderr}")
        return r

    def containers(self, service=None, all_states=True):
        """{name: id} of the project's containers (of one service)."""
        args = ["ps", "--format", "{{.Names}} {{.ID}}", "--filter", f"label=com.docker.compose.project={PROJECT}"]
        if all_states:
            args.insert(1, "-a")
        if service:
            args += ["--filter", f"label=com.docker.compose.service={service}"]
        out = podman(*args).stdout.split()
        return dict(zip(out[::2], out[1::2]))

    def one(self, service):
        (name,) = self.containers(service)
        return name

    def inspect(self, name, fmt):
        return podman("inspect", "-f", fmt, name).stdout.strip()

    def logs(self, name):
        r = podman("logs", name, check=False)
        return r.stdout + r.stderr

    def ip(self, name):
        return self.inspect(name, "{{range .NetworkSettings.Networks}}{{.IPAddress}} {{end}}").split()[0]


def http_json(url, timeout=10):
    with urllib.request.urlopen(url, timeout=timeout) as r:
        return json.loads(r.read().decode())


def prom_query(expr, at=None):
    params = {"query": expr}
    if at is not None:
        params["time"] = f"{at:.3f}"
    answer = http_json("http://127.0.0.1:9090/api/v1/query?" + urllib.parse.urlencode(params))
    assert answer["status"] == "success", answer
    return answer["data"]["result"]


def scraped_counter(ip, family):
    """Sum of a counter family on one /metrics endpoint."""
    with urllib.request.urlopen(f"http://{ip}:9100/metrics", timeout=5) as r:
        text = r.read().decode()
    return sum(float(m.group(1)) for m in re.finditer(rf"^{family}(?:{{[^}}]*}})? (\S+)$", text, re.M))


def metrics_rows():
    return runs.read_metrics(os.path.join(RUNS, "metrics.csv"))


def wait_for(what, done, timeout, poll=1.0):
    deadline = time.time() + timeout
    while True:
        value = done()
        if value:
            return value
        if time.time() > deadline:
            raise RuntimeError(f"timed out after {timeout:.0f} s waiting for {what}")
        time.sleep(poll)


def wait_run(what, done, timeout=1800, stall=120, poll=0.5):
    """wait_for on the run, failing early if metrics.csv stops growing for
    `stall` seconds (a deadlocked run, not a slow one)."""
    last = [None, time.time()]

    def check():
        rows = metrics_rows()
        steps = rows[-1]["env_steps"] if rows else None
        if steps != last[0]:
            last[:] = [steps, time.time()]
        elif time.time() - last[1] > stall:
            raise RuntimeError(f"waiting for {what}: the run made no progress for {stall} s "
                               f"(metrics.csv at {steps} env steps)")
        return done()
    return wait_for(what, check, timeout, poll=poll)


def newest_checkpoint():
    folder = os.path.join(RUNS, "checkpoints")
    found = [int(f.split("-")[1].split(".")[0]) for f in os.listdir(folder) if f.endswith(".meta")] \
        if os.path.isdir(folder) else []
    return max(found, default=None)


def fresh_run_folder():
    """runs/compose as a new run: an earlier one is moved aside, not deleted."""
    if os.path.isdir(RUNS) and any(n != "tls" for n in os.listdir(RUNS)):
        aside = f"{RUNS}.{time.strftime('%Y%m%d-%H%M%S')}"
        os.rename(RUNS, aside)
        say(f"moved the previous runs/compose to {os.path.relpath(aside, ROOT)}")
    os.makedirs(RUNS, exist_ok=True)


STEADY_SCRAPES = 4  # deploy/prometheus/compose.yml scrapes every 15 s: a 45 s window at least


def csv_clock(rows):
    """env steps -> the learner's wall_seconds at which metrics.csv reached
    them, interpolated between rows (its counter moves by whole unrolls,
    between the rows of whole iterations)."""
    points = [(float(r["env_steps"]), float(r["wall_seconds"])) for r in rows]

    def wall(v):
        for (s0, w0), (s1, w1) in zip(points, points[1:]):
            if s0 <= v <= s1:
                return w0 if s1 == s0 else w0 + (w1 - w0) * (v - s0) / (s1 - s0)
        return None
    return wall


def steady_scrapes(rows, t_end=None):
    """(time, value) of the scrapes that first saw each value of the learner's
    env-step counter, past the start-up (15% of the newest value) and within
    metrics.csv's rows."""
    result = prom_query("imca_learner_env_steps_total[15m]", at=t_end)
    if len(result) != 1 or not rows:
        return []
    points = [(float(t), float(v)) for t, v in result[0]["values"]]
    first_seen = {}
    for t, v in points:
        first_seen.setdefault(v, t)
    top = max(v for _, v in points)
    last = float(rows[-1]["env_steps"])
    return sorted((t, v) for v, t in first_seen.items() if 0.15 * top <= v <= last)


def rate_check(figures, t_end):
    """Prometheus's env-step rate against metrics.csv's over the steady part
    of the run before t_end (the first kill): the env steps between two
    scrapes over the time between them, against the same env steps over the
    learner's wall_seconds between the points where metrics.csv reached them.
    The counter moves between rows (by unrolls), so a scrape sees a value at
    most one iteration after the learner reached it, and the two clocks'
    differences over the window differ by at most the longest gap between
    rows: the tolerance is that gap over the window, plus 1% for scrape
    latency. The learner is killed only once there are STEADY_SCRAPES scrapes."""
    rows = metrics_rows()
    steady = steady_scrapes(rows, t_end)
    if len(steady) < 2:
        return figures.add("scrapes in the steady run", len(steady), ">= 2", False)
    wall = csv_clock(rows)
    (t0, v0), (t1, v1) = steady[0], steady[-1]
    scraped = (v1 - v0) / (t1 - t0)
    csv_rate = (v1 - v0) / (wall(v1) - wall(v0))
    window = [float(r["wall_seconds"]) for r in rows if wall(v0) - 5 <= float(r["wall_seconds"]) <= wall(v1) + 5]
    gap = max(b - a for a, b in zip(window, window[1:])) if len(window) > 1 else 0.0
    tolerance = gap / (t1 - t0) + 0.01
    promql = prom_query("rate(imca_learner_env_steps_total[1m])", at=t_end)
    last = next(r for r in reversed(rows) if float(r["env_steps"]) <= v1)
    figures.add("env-step rate, Prometheus vs metrics.csv",
                f"{scraped:,.0f}/s vs {csv_rate:,.0f}/s over {t1 - t0:.0f} s, {len(steady)} scrapes "
                f"(ratio {scraped / csv_rate:.4f}; PromQL rate[1m] {float(promql[0]['value'][1]) if promql else 0:,.0f}/s, "
                f"env_steps_per_sec {float(last['env_steps_per_sec']):,.0f}/s since start)",
                f"|ratio - 1| <= {tolerance:.3f} (longest row gap {gap:.2f} s / window + 1%)",
                abs(scraped / csv_rate - 1) <= tolerance)


def kill_main_process(c, service):
    """kill -9 of a container's main process from the host: a crash, not a stop."""
    name = c.one(service)
    pid = int(c.inspect(name, "{{.State.Pid}}"))
    restarts = int(c.inspect(name, "{{.RestartCount}}") or 0)
    os.kill(pid, signal.SIGKILL)
    say(f"kill -9 {pid} ({name}, main process)")
    return name, restarts


def wait_restarted(c, name, restarts, timeout=90):
    def up():
        state = c.inspect(name, "{{.State.Status}} {{.RestartCount}}").split()
        return state[0] == "running" and int(state[1]) > restarts
    wait_for(f"{name} restarted", up, timeout, poll=0.5)
    return int(c.inspect(name, "{{.RestartCount}}"))


def diagnose(c):
    """What each process says when the run stalls: its key metrics, its last log lines."""
    families = r"imca_(actor|learner)_(policy_version|unrolls_pushed_total|unrolls_refused_total|unrolls_resent_total|" \
               r"reconnects_total|retries_total|policy_polls_waiting|unroll_streams|pushers_waiting|queue_depth|" \
               r"env_steps_total)"
    for name in sorted(c.containers()):
        if c.inspect(name, "{{.State.Status}}") != "running":
            say(f"{name}: {c.inspect(name, '{{.State.Status}} {{.State.ExitCode}}')}")
            continue
        try:
            with urllib.request.urlopen(f"http://{c.ip(name)}:9100/metrics", timeout=5) as r:
                text = r.read().decode()
            say(f"{name}: " + ", ".join(f"{m.group(1)} {m.group(4)}" for m in re.finditer(
                rf"^({families})(?:{{[^}}]*}})? (\S+)$", text, re.M)))
        except OSError as e:
            say(f"{name}: no metrics ({e})")
        say(f"{name} log tail:\n" + "\n".join(c.logs(name).splitlines()[-4:]))


def same_configuration(figures):
    """(a)'s premise: the compose services resolve the configuration that
    ./imca train runs with the same overrides (its config.json's
    "resolved"), asked of the image's own binaries (--print_config)."""
    with open(COMPOSE) as f:
        services = yaml.safe_load(f)["services"]
    argv, flags = [], {}
    for program in binaries.PROGRAMS:
        train_flag = {programs[program]: flag for flag, programs, _ in options.all_options() if program in programs}
        command = services[program]["command"]
        # The training flags only: wiring (addresses, files, secrets) is the deployment's.
        flags[program] = [a for a in command[1:] if a[2:].partition("=")[0] in train_flag]
        for a in flags[program]:
            name, _, value = a[2:].partition("=")
            if train_flag[name] not in argv:
                argv += [train_flag[name], value]
    _, config = plan.plan(plan.parse_args(argv))
    differ = []
    for program in binaries.PROGRAMS:
        out = podman("run", "--rm", IMAGE, program, *flags[program], "--print_config")
        if json.loads(out.stdout) != config["resolved"][program]:
            differ.append(program)
    return figures.add("compose trains ./imca train's configuration",
                       f"./imca train {' '.join(argv)}: {'same' if not differ else 'differs: ' + ', '.join(differ)}",
                       "the image's --print_config = config.json's resolved, each service", not differ)


def compose_test(figures, docker_host, steps, actors):
    """The compose run with `actors` actor replicas (its deploy.replicas)."""
    fresh_run_folder()
    make_certs()
    c = Compose(docker_host, steps)
    events = None
    same_configuration(figures)
    try:
        started = time.time()
        c("up", "-d", "--no-build", "--scale", f"actor={actors}")
        c.started = True
        say(f"compose up: {c.containers()}")

        # (b) every target up, once the actors are found through DNS.
        def targets():
            try:
                active = http_json("http://127.0.0.1:9090/api/v1/targets")["data"]["activeTargets"]
            except OSError:
                return None
            return active if len(active) == 2 + actors and all(t["health"] == "up" for t in active) else None
        try:
            active = wait_for("every Prometheus target up", targets, 120, poll=2)
            figures.add("Prometheus targets up", f"{len(active)}/{len(active)} "
                        f"({', '.join(sorted(t['labels']['job'] for t in active))})", f"{2 + actors} up", True)
        except RuntimeError:
            active = http_json("http://127.0.0.1:9090/api/v1/targets")["data"]["activeTargets"]
            figures.add("Prometheus targets up", [(t["labels"]["job"], t["health"], t.get("lastError"))
                                                  for t in active], f"{2 + actors} up", False)

        # (c) the learner killed past half the budget (past 70% with fewer
        # scrapes), at once after a new checkpoint: it resumes at, or just
        # behind, the version the actors hold, with none of the unrolls of it
        # they delivered; at the same version, only the learner's new
        # incarnation tells them to act their share again
        # (actor_test.cc, ...ActsItsShareAgainForALearnerRestartedAtItsVersion).
        said = [0.0]
        ready_at = [None]  # The newest checkpoint once past half the budget.

        def half_way():
            rows = metrics_rows()
            checkpoint = newest_checkpoint()
            if not (rows and int(rows[-1]["env_steps"]) >= steps // 2 and checkpoint is not None):
                return False
            scrapes = len(steady_scrapes(rows))
            if time.time() - said[0] > 10:
                said[0] = time.time()
                say(f"iteration {rows[-1]['iteration']}, newest checkpoint {checkpoint}, {scrapes} steady scrapes")
            if ready_at[0] is None:
                if scrapes >= STEADY_SCRAPES or int(rows[-1]["env_steps"]) >= 0.7 * steps:
                    ready_at[0] = checkpoint
                return False
            return checkpoint > ready_at[0]
        wait_run("half the budget and a new checkpoint", half_way, poll=0.05)
        t_kill = time.time()
        learner, restarts = kill_main_process(c, "learner")
        killed_after = int(metrics_rows()[-1]["iteration"]) - newest_checkpoint()
        rate_check(figures, t_kill)  # Over the scrapes before the kill.
        before = c.logs(learner).count("resumed at policy version")
        count = wait_restarted(c, learner, restarts)
        log = wait_for("the learner's resume line", lambda: (lambda t: t if t.count(
            "resumed at policy version") > before else None)(c.logs(learner)), 120, poll=0.5)
        version = int(log.rsplit("resumed at policy version ", 1)[1].split()[0])
        figures.add("learner kill -9: restarted and resumed",
                    f"restart {count}, resumed at policy version {version} (killed {killed_after} iteration(s) "
                    "after that checkpoint)", "restarted by compose, version > 0", version > 0)

        # The reward server at three quarters: every answered count survives.
        wait_run("three quarters of the budget",
                 lambda: (r := metrics_rows()) and int(r[-1]["env_steps"]) >= 3 * steps // 4)
        actor_ips = [c.ip(n) for n in c.containers("actor")]
        reward, restarts = kill_main_process(c, "reward_server")
        # Right after the kill, before the replacement answers: what the
        # actors had been answered (their transitions_scored counters).
        answered = sum(scraped_counter(ip, "imca_actor_transitions_scored_total") for ip in actor_ips)
        count = wait_restarted(c, reward, restarts)
        log = wait_for("the reward server's restore line",
                       lambda: (m := re.findall(r"restored from \S+ \((\d+) transitions counted\)",
                                                c.logs(reward))) and m, 120, poll=0.5)
        restored = int(log[-1])
        figures.add("reward server kill -9: restarted, counts kept",
                    f"restart {count}, restored {restored:,} transitions counted, {answered:,.0f} answered before "
                    f"the kill ({restored - answered:+,.0f} counted but unanswered)",
                    "restored >= answered > 0", restored >= answered > 0)

        # The budget: the learner exits 0 after lingering, the actors 0.
        learner_state = wait_run("the learner to finish", lambda: (s := c.inspect(
            learner, "{{.State.Status}} {{.State.ExitCode}}").split()) and s[0] == "exited" and s)
        rows = metrics_rows()
        final = int(rows[-1]["env_steps"])
        elapsed = time.time() - started
        figures.add("run reaches its budget", f"{final:,} env steps, learner exit {learner_state[1]}, "
                    f"{elapsed:.0f} s wall", f">= {steps:,}, exit 0",
                    final >= steps and learner_state[1] == "0")
        reached = runs.first_reaching(rows, 0.9)
        figures.add("coop_nav env steps to 90% evaluation success",
                    f"{int(reached['env_steps']):,} (success {float(reached['success_rate']):.1%})" if reached else
                    f"not reached (best {max(float(r['success_rate']) for r in rows):.1%})", "<= 1,000,000",
                    reached is not None and int(reached["env_steps"]) <= 1_000_000)
        for name in c.containers("actor"):
            wait_for(f"{name} to exit", lambda: c.inspect(name, "{{.State.Status}}") == "exited", 120)
        codes = {n: c.inspect(n, "{{.State.ExitCode}}") for n in c.containers("actor")}
        codes[learner] = learner_state[1]

        # (d) docker-compose down: the containers still running get SIGTERM
        # (exit codes read from podman's died events, the containers being
        # removed), and none is left.
        since = time.time()
        running = c.containers(all_states=False)
        events = subprocess.Popen(["podman", "events", "--since", f"{since:.0f}", "--filter", "event=died",
                                   "--format", "{{.Name}} {{.ContainerExitCode}}"], stdout=subprocess.PIPE, text=True)
        down_started = time.time()
        c("down", "--volumes", timeout=300)
        down_seconds = time.time() - down_started
        c.started = False
        time.sleep(2)
        events.terminate()
        died = dict(line.split() for line in events.communicate(timeout=10)[0].splitlines() if line.strip())
        for name in running:
            codes[name] = died.get(name, "none seen")
        left = c.containers()
        expected = {n: "0" for n in codes}  # docs/deploy.md: exit codes
        figures.add("docker-compose down: exit codes", ", ".join(f"{n.replace(PROJECT + '_', '')} {v}"
                                                                 for n, v in sorted(codes.items())) +
                    f"; down took {down_seconds:.0f} s, {len(left)} containers left",
                    "every one 0 (docs/deploy.md), none left", codes == expected and not left)
    except RuntimeError:
        if c.started:
            diagnose(c)
        raise
    finally:
        if events is not None and events.poll() is None:
            events.kill()
        if c.started:
            say("tearing compose down")
            c("down", "--volumes", check=False, timeout=300)


# --------------------------------------------------------------------- image

def scan_image(figures):
    """(e) No key material, tokens, certificates of ours or run output in the
    image: its files, mounted from the host."""
    mount = podman("image", "mount", IMAGE).stdout.strip()
    found = []
    try:
        for top, dirs, files in os.walk(mount):
            rel = os.path.relpath(top, mount)
            if rel.split(os.sep)[0] in ("proc", "sys", "dev"):
                continue
            for d in dirs:
                if d in ("results", "runs", "tls", ".git", "build") or d.startswith("build-"):
                    found.append(os.path.join(rel, d) + "/")
            for f in files:
                path = os.path.join(top, f)
                if f.endswith((".key", ".csr")) or f == "token" or f.endswith(".token"):
                    found.append(os.path.join(rel, f))
                elif os.path.isfile(path) and not os.path.islink(path) and os.path.getsize(path) < 1 << 20:
                    with open(path, "rb") as fh:
                        data = fh.read()
                    if b"\0" not in data and re.search(rb"-----BEGIN [A-Z ]*PRIVATE KEY-----", data):
                        found.append(os.path.join(rel, f) + " (a private key)")
    finally:
        podman("image", "unmount", IMAGE, check=False)
    size = podman("image", "inspect", "-f", "{{.Size}}", IMAGE).stdout.strip()
    # Every library of every binary resolves in the image, the OpenMP
    # OpenBLAS is libblas.so.3 (deploy/packages.txt's runtime packages).
    ldd = podman("run", "--rm", IMAGE, "sh", "-c", "ldd " + " ".join(f"/usr/local/bin/{b}" for b in IMAGE_BINARIES)
                 + " | grep 'not found'; readlink -f /usr/lib/x86_64-linux-gnu/libblas.so.3", check=False).stdout
    *unresolved, blas = ldd.split("\n")[:-1] or ["?"]
    figures.add("image: every library resolves, libblas.so.3 is OpenBLAS (OpenMP)",
                f"{len(unresolved)} not found; {blas}", "0; openblas-openmp",
                not unresolved and "openblas-openmp" in blas)
    figures.add("image carries no keys, tokens or run output", ", ".join(found) or f"none ({int(size) / 1e6:.0f} MB)",
                "none", not found)


def scan_context(figures):
    """.dockerignore: what a from-source build would send (a COPY . of the
    repository root with it), for the same names."""
    with tempfile.TemporaryDirectory(prefix="imca-ctx-") as tmp:
        dockerfile = os.path.join(tmp, "Dockerfile")
        with open(dockerfile, "w") as f:
            f.write("FROM debian:12\nCOPY . /ctx\n")
        podman("build", "-q", "-f", dockerfile, "-t", "localhost/imca-context-check:latest", ROOT)
        try:
            r = podman("run", "--rm", "localhost/imca-context-check:latest", "sh", "-c",
                       "cd /ctx && find . \\( -name '*.key' -o -name '*.pem' -o -name token -o -name __pycache__ "
                       "-o -path ./results -o -path ./runs -o -path ./.git -o -name 'build*' -type d \\) -print; "
                       "du -sm . | cut -f1")
        finally:
            podman("rmi", "localhost/imca-context-check:latest", check=False)
    *found, size = r.stdout.split()
    figures.add(".dockerignore keeps results, runs, .git, builds, keys out of the context",
                ", ".join(found) or f"none ({size} MB context)", "none", not found)


# ---------------------------------------------------------------- experiment

def experiment_pod_test(figures):
    """The pod of ./imca experiment --backend k8s, in the image: the Indexed
    Job's container command for a small cell, with the claim and the
    ConfigMap as folders and JOB_COMPLETION_INDEX set as the Job controller
    sets it, trains the cell to its budget."""
    cell, = grid.expand([{"scenario": "coop_nav", "reward": "count", "credit": "imca", "steps": 16000,
                                "flags": {"actors": 1, "envs_per_actor": 8, "batch_steps": 1024}}], "pod")
    record = {"number": 1, "backend": "k8s", "cells": [cell]}
    res = dict(cluster.DEFAULT_RESOURCES, cpus_per_task=1, mem="2G")
    config_map, job = cluster.k8s_manifest(record, "/results/pod", res, 0, IMAGE, "imca-results", "/results/pod")
    (container,) = job["spec"]["template"]["spec"]["containers"]
    mounts = {m["name"]: m["mountPath"] for m in container["volumeMounts"]}
    with tempfile.TemporaryDirectory(prefix="imca-pod-") as tmp:
        claim, queue = os.path.join(tmp, "claim"), os.path.join(tmp, "queue")
        os.makedirs(claim)
        os.makedirs(queue)
        for name, text in config_map["data"].items():
            with open(os.path.join(queue, name), "w") as f:
                f.write(text)
        started = time.time()
        r = podman("run", "--rm", "-e", "JOB_COMPLETION_INDEX=0", "-v", f"{claim}:{mounts['results']}",
                   "-v", f"{queue}:{mounts['queue']}:ro", IMAGE, *container["command"], check=False, timeout=600)
        run_dir = grid.cell_dir(os.path.join(claim, "pod"), cell)
        summary = runner.finished(run_dir, cell)
        # The run folder as a local run leaves it, its pictures included.
        missing = [f for f in ("learning_curve.png", "episode.gif") if not os.path.exists(os.path.join(run_dir, f))]
        log = open(os.path.join(run_dir, "train.log")).read() if os.path.exists(run_dir) else ""
        if summary and (missing or "Traceback" in log):
            summary = None
            r.stderr += f"\nmissing {missing}, train.log: {log[-500:]}"
        figures.add("experiment pod (--backend k8s) in the image: its cell trains to the budget",
                    f"exit {r.returncode}, {summary['env_steps'] if summary else 'no summary'} env steps "
                    f"in {time.time() - started:.0f} s" if summary else
                    f"exit {r.returncode}: {(r.stdout + r.stderr).strip().splitlines()[-1:]}",
                    f">= {cell['steps']}", r.returncode == 0 and summary is not None)


# ---------------------------------------------------------------------- kube

def smoke_manifest(path, state_claim):
    """The reward server's Deployment from deploy/k8s/imca.yaml and its claim
    from deploy/k8s/volumes, for podman 4.3's kube play: the Secret imca-tls
    becomes a hostPath of runs/compose/tls (kube play mounts Secret data still
    base64-encoded: podman bug 16625), the claim gets a name of its own."""
    with open(os.path.join(DEPLOY, "k8s", "imca.yaml")) as f:
        docs = [d for d in yaml.safe_load_all(f) if d]
    (deployment,) = [d for d in docs if d["kind"] == "Deployment"
                     and d["spec"]["template"]["spec"]["containers"][0]["command"] == ["reward_server"]]
    with open(os.path.join(DEPLOY, "k8s", "volumes", "volumes.yaml")) as f:
        volumes = [d for d in yaml.safe_load_all(f) if d]
    pod = deployment["spec"]["template"]["spec"]
    claim = None
    for v in pod["volumes"]:
        if "secret" in v:
            items = v.pop("secret")["items"]
            v["hostPath"] = {"path": TLS, "type": "Directory"}
            for item in items:
                assert os.path.exists(os.path.join(TLS, item["path"])), item
        elif "persistentVolumeClaim" in v:
            claim = v["persistentVolumeClaim"]["claimName"]
            v["persistentVolumeClaim"]["claimName"] = state_claim
    (pvc,) = [d for d in volumes if d["kind"] == "PersistentVolumeClaim" and d["metadata"]["name"] == claim]
    pvc["metadata"]["name"] = state_claim
    container = pod["containers"][0]
    container["image"] = IMAGE
    with open(path, "w") as f:
        yaml.safe_dump_all([pvc, deployment], f, sort_keys=False)
    return container


def kube_test(figures):
    say("kube play: the reward server's Deployment (deploy/k8s/imca.yaml); its Secret imca-tls is mounted as a "
        "hostPath of runs/compose/tls instead: podman 4.3 mounts Secret data base64-encoded (bug 16625)")
    if not os.path.exists(os.path.join(TLS, "probe.key")):
        make_certs()
    claim = "imca-reward-smoke"
    with tempfile.TemporaryDirectory(prefix="imca-kube-") as tmp:
        manifest = os.path.join(tmp, "reward-server.yaml")
        container = smoke_manifest(manifest, claim)
        played = False
        # kube play makes this network when it is missing; so it goes again.
        network = "podman-default-kube-network"
        had_network = podman("network", "exists", network, check=False).returncode == 0
        try:
            started = time.time()
            # From a folder of its own: podman 4.3's kube play looks for a
            # build folder named like the image in its working directory, even
            # with --build=false (and ./imca is a file).
            played = True  # Torn down even if it fails half-way.
            out = podman("kube", "play", "--build=false", manifest, quiet=False, cwd=tmp).stdout
            (pod,) = re.findall(r"^Pod:\n(\S+)", out, re.M)
            name = next(n for n in podman("ps", "-a", "--filter", f"pod={pod}", "--format", "{{.Names}}").stdout.split()
                        if n.endswith("-" + container["name"]))

            def serving():
                state = podman("inspect", "-f", "{{.State.Status}}", name).stdout.strip()
                if state != "running":
                    raise RuntimeError(f"{name} is {state}: {podman('logs', name, check=False).stderr[-2000:]}")
                r = podman("exec", name, *container["readinessProbe"]["exec"]["command"], check=False)
                return r if r.returncode == 0 and "SERVING" in r.stdout else None
            probe = wait_for("the readiness probe", serving, 60, poll=1)
            figures.add("kube play: pod running, readiness probe (imca_health over mTLS)",
                        f"{probe.stdout.strip()} after {time.time() - started:.1f} s", "SERVING", True)
            # The liveness probe is the container's healthcheck under podman.
            health = podman("healthcheck", "run", name, check=False)
            figures.add("kube play: liveness probe as podman healthcheck", f"exit {health.returncode} "
                        f"{(health.stdout + health.stderr).strip()}", "exit 0", health.returncode == 0)
            # Mutual TLS from outside the pod: the probe's certificate is
            # served, no client certificate is refused.
            infra = podman("pod", "inspect", "-f", "{{.InfraContainerID}}", pod).stdout.strip()
            ip = podman("inspect", "-f", "{{range .NetworkSettings.Networks}}{{.IPAddress}} {{end}}",
                        infra).stdout.split()[0]
            target = [os.path.join(BIN, "imca_health"), f"--target={ip}:50051", f"--tls_ca={TLS}/ca.pem",
                      "--tls_server_name=reward-server"]
            with_cert = run(target + [f"--tls_cert={TLS}/probe.pem", f"--tls_key={TLS}/probe.key"], check=False,
                            quiet=True)
            without = run(target, check=False, quiet=True)
            figures.add("kube play: mutual TLS from the host", f"with the probe certificate: exit {with_cert.returncode} "
                        f"{with_cert.stdout.strip()}; without a client certificate: exit {without.returncode} "
                        f"({(without.stdout + without.stderr).strip().splitlines()[-1][:160] if without.stdout + without.stderr else ''})",
                        "served; refused", with_cert.returncode == 0 and "SERVING" in with_cert.stdout
                        and without.returncode != 0)
        finally:
            if played:
                podman("kube", "play", "--down", manifest, check=False, cwd=tmp)
            podman("volume", "rm", "-f", claim, check=False)
            if not had_network:
                podman("network", "rm", network, check=False)


# ---------------------------------------------------------------------- main

def interrupted(signum, frame):
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv=None):
    p = argparse.ArgumentParser(prog="./imca deploy-test", description=__doc__.split("\n\n")[0])
    p.add_argument("part", nargs="?", default="all", choices=("all", "image", "compose", "kube", "experiment"))
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--prebuilt", dest="from_source", action="store_false",
                      help="(default) the image's runtime stage over the host's build/bin: no compile")
    mode.add_argument("--from-source", dest="from_source", action="store_true",
                      help="the image from deploy/Dockerfile as it is (compiles everything)")
    p.set_defaults(from_source=False)
    p.add_argument("--steps", type=int, default=None,
                   help="the compose learner's budget (default: the learner's, as the compose file trains; "
                        "another comes in an override file)")
    p.add_argument("--reuse-image", action="store_true", help="use an existing imca image as it is")
    args = p.parse_args(options.dashed(sys.argv[1:] if argv is None else argv))
    # SIGTERM tears down as Ctrl-C does (the finally blocks).
    signal.signal(signal.SIGTERM, interrupted)
    figures = Figures()
    timings = {}
    code = 0
    try:
        setup_engine()
        t = time.time()
        how = make_base()
        timings["debian:12 base"] = f"{time.time() - t:.0f} s ({how})"
        if args.reuse_image and podman("image", "exists", IMAGE, check=False).returncode == 0:
            timings["imca image"] = "reused"
        else:
            timings["imca image"] = (f"{build_image(args.from_source):.0f} s "
                                     f"({'from source' if args.from_source else 'prebuilt build/bin'})")
        if args.part in ("all", "image"):
            scan_image(figures)
            scan_context(figures)
        if args.part in ("all", "compose"):
            timings["Prometheus image"] = f"{build_prometheus():.0f} s"
            with podman_service() as docker_host:
                t = time.time()
                try:
                    steps = learner_default_steps() if args.steps is None else args.steps
                    compose_test(figures, docker_host, steps, compose_actors())
                finally:
                    timings["compose run"] = f"{time.time() - t:.0f} s"
        if args.part in ("all", "kube"):
            kube_test(figures)
        if args.part in ("all", "experiment"):
            experiment_pod_test(figures)
    except Exception as e:  # A step that could not run is a failed check too.
        figures.add("the test ran to its end", f"{type(e).__name__}: {e}", "no error", False)
    print("\n" + "\n".join(f"{k}: {v}" for k, v in timings.items()))
    print("\n" + figures.table())
    if figures.failed():
        code = 1
        print(f"\n{len(figures.failed())} check(s) failed")
    return code


if __name__ == "__main__":
    sys.exit(main())
