#!/usr/bin/python3
"""The Prometheus endpoints of a real run, scraped by a real Prometheus.

One short `./imca train --metrics-port N` (reward server, learner, two actors
on loopback) runs while Debian's Prometheus server scrapes it four times a
second with deploy/prometheus/rules.yml loaded. Every endpoint must pass
`promtool check metrics`, parse with Debian's prometheus_client, and keep the
invariants promtool does not check (histogram buckets increasing and ending
in +Inf equal to _count, no duplicate series, one HELP and TYPE per family
before its samples, no high-cardinality label). Through the server's HTTP
query API every target must be up and the env-step rate positive, and the
rate Prometheus saw must agree with metrics.csv within 5%.
"""
import json
import math
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import unittest
import urllib.parse
import urllib.request

from prometheus_client.parser import text_string_to_metric_families

from imca_tools import binaries, runs

ROOT = os.environ.get("IMCA_ROOT", os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("IMCA_BIN", os.path.join(ROOT, "build", "bin"))

ACTORS = 2
STEPS = 1_000_000
# Label names a series may carry: small fixed sets only (no agent, actor id
# or episode: docs/metrics.md).
ALLOWED_LABELS = {"service", "method", "code", "reason", "phase", "le"}
# Families each job must export (the list, by the names we chose).
REQUIRED = {
    "reward_server": ["imca_reward_transitions_scored_total", "imca_reward_requests_total",
                      "imca_reward_requests_rejected_total", "imca_reward_table_entries",
                      "imca_reward_model_updates_total", "imca_reward_score_seconds_total",
                      "imca_reward_score_handler_seconds_total", "imca_rpc_server_handled_total",
                      "imca_rpc_server_handling_seconds", "process_resident_memory_bytes"],
    "learner": ["imca_learner_unrolls_received_total", "imca_learner_env_steps_total",
                "imca_learner_iterations_total", "imca_learner_gradient_steps_total", "imca_learner_queue_depth",
                "imca_learner_policy_lag_versions", "imca_learner_unrolls_dropped_total",
                "imca_learner_unroll_streams", "imca_learner_actor_incarnations_total",
                "imca_rpc_server_handled_total", "imca_rpc_server_handling_seconds",
                "process_resident_memory_bytes"],
    "actor": ["imca_actor_env_steps_total", "imca_actor_unrolls_pushed_total", "imca_actor_reconnects_total",
              "imca_actor_transitions_scored_total", "imca_actor_phase_seconds_total", "imca_rpc_client_handled_total",
              "imca_rpc_client_handling_seconds", "process_resident_memory_bytes"],
}

SAMPLE = re.compile(r'^([a-zA-Z_:][a-zA-Z0-9_:]*)(\{(.*)\})? (\S+)$')
LABEL = re.compile(r'([a-zA-Z_][a-zA-Z0-9_]*)="((?:[^"\\]|\\.)*)"(,|$)')


def parse_value(text):
    return float(text.replace("Inf", "inf"))  # "+Inf", "-Inf", "NaN" and numbers.


def exposition_problems(text):
    """What is wrong with a text exposition beyond what promtool checks."""
    problems = []
    if not text.endswith("\n"):
        problems.append("the last line does not end with a line feed")
    helps, types, seen_series, families_done = {}, {}, set(), set()
    current = None
    histograms = {}  # (family, labels without le) -> {"buckets": [(le, v)], "count": v, "sum": v}
    for n, line in enumerate(text.splitlines(), 1):
        if line.startswith("# HELP ") or line.startswith("# TYPE "):
            kind, name = line[2:6], line.split(" ")[2]
            table = helps if kind == "HELP" else types
            if name in table:
                problems.append(f"line {n}: a second {kind} for {name}")
            table[name] = line.split(" ", 3)[3] if kind == "TYPE" else True
            if name != current:
                if current is not None:
                    families_done.add(current)
                if name in families_done:
                    problems.append(f"line {n}: {name} is split into more than one group")
                current = name
            continue
        if line.startswith("#") or not line:
            continue
        m = SAMPLE.match(line)
        if not m:
            problems.append(f"line {n}: not a sample: {line!r}")
            continue
        name, labels_text, value = m.group(1), m.group(3) or "", parse_value(m.group(4))
        labels = tuple((k, v) for k, v, _ in LABEL.findall(labels_text))
        base = re.sub(r"_(bucket|sum|count)$", "", name)
        family = base if types.get(base) == "histogram" else name
        if family not in types:
            problems.append(f"line {n}: {name} has no TYPE before its samples")
        if family != current:
            problems.append(f"line {n}: {name} is outside its family's group")
        if (name, labels) in seen_series:
            problems.append(f"line {n}: duplicate series {name}{dict(labels)}")
        seen_series.add((name, labels))
        for key, _ in labels:
            if key not in ALLOWED_LABELS:
                problems.append(f"line {n}: {name} has label {key!r}, not one of {sorted(ALLOWED_LABELS)}")
        if types.get(family) == "counter" and not name.endswith("_total"):
            problems.append(f"line {n}: counter {name} does not end in _total")
        if types.get(family) == "histogram":
            key = (family, tuple(l for l in labels if l[0] != "le"))
            h = histograms.setdefault(key, {"buckets": [], "count": None, "sum": None})
            if name.endswith("_bucket"):
                le = dict(labels).get("le")
                h["buckets"].append((math.inf if le == "+Inf" else float(le), value))
            elif name.endswith("_count"):
                h["count"] = value
            elif name.endswith("_sum"):
                h["sum"] = value
    for (family, labels), h in histograms.items():
        where = f"{family}{dict(labels)}"
        les = [le for le, _ in h["buckets"]]
        if les != sorted(les) or len(set(les)) != len(les):
            problems.append(f"{where}: bucket bounds not strictly increasing: {les}")
        values = [v for _, v in h["buckets"]]
        if any(b < a for a, b in zip(values, values[1:])):
            problems.append(f"{where}: cumulative bucket counts decrease: {values}")
        if not les or les[-1] != math.inf:
            problems.append(f"{where}: no le=\"+Inf\" bucket")
        elif h["count"] != values[-1]:
            problems.append(f"{where}: +Inf bucket {values[-1]} is not _count {h['count']}")
        if h["sum"] is None or h["count"] is None:
            problems.append(f"{where}: no _sum or _count")
    return problems


def free_ports(count):
    """A base port with `count` consecutive free ports on 127.0.0.1."""
    for _ in range(200):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            base = s.getsockname()[1]
        if base + count >= 65535:
            continue
        sockets = []
        try:
            for port in range(base, base + count):
                s = socket.socket()
                sockets.append(s)
                s.bind(("127.0.0.1", port))
            return base
        except OSError:
            continue
        finally:
            for s in sockets:
                s.close()
    raise RuntimeError("no block of free ports")


def read(path):
    with open(path) as f:
        return f.read()


def http_get(url, timeout=5):
    with urllib.request.urlopen(url, timeout=timeout) as r:
        return r.read().decode(), r.headers.get("Content-Type")


class PrometheusScrapeTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="imca-metrics-")
        cls.base = free_ports(2 + ACTORS)
        cls.prom_port = free_ports(1)
        cls.jobs = {"reward_server": [cls.base], "learner": [cls.base + 1],
                    "actor": [cls.base + 2 + i for i in range(ACTORS)]}
        config = os.path.join(cls.tmp, "prometheus.yml")
        with open(config, "w") as f:
            f.write("global: {scrape_interval: 250ms, scrape_timeout: 200ms, evaluation_interval: 1s}\n"
                    f"rule_files: [{json.dumps(os.path.join(ROOT, 'deploy', 'prometheus', 'rules.yml'))}]\n"
                    "scrape_configs:\n")
            for job, ports in cls.jobs.items():
                targets = ", ".join(f'"127.0.0.1:{p}"' for p in ports)
                f.write(f"  - job_name: {job}\n    static_configs: [{{targets: [{targets}]}}]\n")
        cls.prom_log = open(os.path.join(cls.tmp, "prometheus.log"), "w")
        cls.prometheus = subprocess.Popen(
            ["prometheus", f"--config.file={config}", f"--storage.tsdb.path={os.path.join(cls.tmp, 'tsdb')}",
             f"--web.listen-address=127.0.0.1:{cls.prom_port}", "--log.level=warn"],
            stdout=cls.prom_log, stderr=subprocess.STDOUT)
        cls.api = f"http://127.0.0.1:{cls.prom_port}"
        deadline = time.time() + 60
        while True:
            try:
                http_get(cls.api + "/-/ready")
                break
            except OSError:
                if time.time() > deadline or cls.prometheus.poll() is not None:
                    raise RuntimeError("prometheus did not start: " + read(cls.prom_log.name))
                time.sleep(0.2)

        cls.run_dir = os.path.join(cls.tmp, "run")
        cls.train_log = open(os.path.join(cls.tmp, "train.log"), "w")
        cls.train = subprocess.Popen(
            [*binaries.module_argv("train"), f"--steps={STEPS}", f"--actors={ACTORS}",
             f"--metrics-port={cls.base}", f"--out={cls.run_dir}", "--quiet"],
            stdout=cls.train_log, stderr=subprocess.STDOUT)
        # Mid-run: each endpoint's text once the learner trains, and what
        # Prometheus says of its targets.
        cls.texts, cls.content_types = {}, {}
        cls.up, cls.rate = None, None
        deadline = time.time() + 240
        try:
            while time.time() < deadline and cls.train.poll() is None:
                try:
                    learner, _ = http_get(f"http://127.0.0.1:{cls.base + 1}/metrics")
                except OSError:
                    time.sleep(0.2)
                    continue
                if re.search(r"^imca_learner_iterations_total [1-9]", learner, re.M):
                    break
                time.sleep(0.2)
            time.sleep(3)  # Some scrapes of every target.
            for job, ports in cls.jobs.items():
                for port in ports:
                    cls.texts[(job, port)], cls.content_types[(job, port)] = http_get(
                        f"http://127.0.0.1:{port}/metrics")
            targets = 2 + ACTORS
            cls.up = cls.query_until("up", lambda r: len(r) == targets and all(x["value"][1] == "1" for x in r))
            cls.raw_rate = cls.query_until("rate(imca_learner_env_steps_total[2s])",
                                           lambda r: r and float(r[0]["value"][1]) > 0)
            # The rule group evaluates once a second, from some offset.
            cls.rate = cls.query_until("imca:learner_env_steps:rate1m", lambda r: r and float(r[0]["value"][1]) > 0)
        finally:
            cls.train_code = cls.train.wait(timeout=600)
        cls.samples = cls.query("imca_learner_env_steps_total[10m]")

    @classmethod
    def tearDownClass(cls):
        for proc in (cls.train, cls.prometheus):
            if proc.poll() is None:
                proc.terminate()
                proc.wait(timeout=30)
        cls.prom_log.close()
        cls.train_log.close()
        shutil.rmtree(cls.tmp, ignore_errors=True)

    @classmethod
    def query(cls, expr):
        body, _ = http_get(cls.api + "/api/v1/query?" + urllib.parse.urlencode({"query": expr}))
        answer = json.loads(body)
        assert answer["status"] == "success", answer
        return answer["data"]["result"]

    @classmethod
    def query_until(cls, expr, done, timeout=15):
        """The query's result once `done(result)` holds (or the last one after `timeout` s)."""
        deadline = time.time() + timeout
        while True:
            result = cls.query(expr)
            if done(result) or time.time() > deadline:
                return result
            time.sleep(0.25)

    def test_the_run_trains_to_its_budget(self):
        self.assertEqual(self.train_code, 0, read(self.train_log.name))

    def test_every_endpoint_passes_promtool_check_metrics(self):
        self.assertEqual(len(self.texts), 2 + ACTORS)
        for (job, port), text in self.texts.items():
            r = subprocess.run(["promtool", "check", "metrics"], input=text, capture_output=True, text=True)
            self.assertEqual(r.returncode, 0, f"{job} :{port}: {r.stdout}{r.stderr}")
            self.assertEqual(self.content_types[(job, port)], "text/plain; version=0.0.4; charset=utf-8")

    def test_every_endpoint_keeps_the_invariants_promtool_misses(self):
        for (job, port), text in self.texts.items():
            self.assertEqual(exposition_problems(text), [], f"{job} :{port}")
            families = {f.name: f for f in text_string_to_metric_families(text)}
            for name in REQUIRED[job]:
                # The client names counters without _total.
                self.assertIn(re.sub(r"_total$", "", name), families, f"{job}: no {name}")

    def test_the_checker_catches_what_promtool_misses(self):
        good = ("# HELP h_seconds H.\n# TYPE h_seconds histogram\nh_seconds_bucket{le=\"1\"} 1\n"
                "h_seconds_bucket{le=\"+Inf\"} 2\nh_seconds_sum 3\nh_seconds_count 2\n")
        self.assertEqual(exposition_problems(good), [])
        broken = {
            "decreasing": good.replace('le="1"} 1', 'le="1"} 5'),
            "no +Inf": good.replace('h_seconds_bucket{le="+Inf"} 2\n', ""),
            "+Inf is not _count": good.replace("h_seconds_count 2", "h_seconds_count 7"),
            "duplicate": good + 'h_seconds_bucket{le="1"} 1\n',
            "unordered bounds": good.replace('le="1"', 'le="9"').replace(
                'h_seconds_bucket{le="+Inf"}', 'h_seconds_bucket{le="2"} 1\nh_seconds_bucket{le="+Inf"}'),
            "agent label": good.replace('{le="1"}', '{agent="3",le="1"}'),
            "no final newline": good.rstrip("\n"),
            "second HELP": good + "# HELP h_seconds again\n",
        }
        for what, text in broken.items():
            self.assertNotEqual(exposition_problems(text), [], what)
        # promtool itself lets a histogram without its +Inf bucket through.
        r = subprocess.run(["promtool", "check", "metrics"], input=broken["no +Inf"], capture_output=True,
                           text=True)
        self.assertEqual(r.returncode, 0, "promtool now catches a missing +Inf: the check here may go")

    def test_prometheus_scrapes_every_target_up(self):
        up = {(r["metric"]["job"], r["metric"]["instance"]): r["value"][1] for r in self.up}
        expected = {(job, f"127.0.0.1:{p}") for job, ports in self.jobs.items() for p in ports}
        self.assertEqual(set(up), expected)
        self.assertEqual(set(up.values()), {"1"}, up)

    def test_the_env_step_rate_is_positive(self):
        self.assertEqual(len(self.raw_rate), 1, self.raw_rate)
        self.assertGreater(float(self.raw_rate[0]["value"][1]), 0)
        # The recording rule of deploy/prometheus/rules.yml evaluates too.
        self.assertEqual(len(self.rate), 1, self.rate)
        self.assertGreater(float(self.rate[0]["value"][1]), 0)

    def test_the_scraped_env_step_rate_agrees_with_metrics_csv(self):
        """Between the first and last scrapes of the steady run, Prometheus's
        rate (its own clock, its scrape times) and metrics.csv's (the learner's
        wall_seconds between the rows holding the same env_steps) agree."""
        self.assertEqual(len(self.samples), 1)
        points = [(float(t), float(v)) for t, v in self.samples[0]["values"]]
        rows = runs.read_metrics(os.path.join(self.run_dir, "metrics.csv"))
        wall = {int(r["env_steps"]): float(r["wall_seconds"]) for r in rows}
        final = max(v for _, v in points)
        # The steady part: past a fifth of the budget (start-up), before the
        # final value (sampled after training stopped). A value stays put
        # between iterations: take each value's first sample.
        first_seen = {}
        for t, v in points:
            first_seen.setdefault(v, t)
        steady = sorted((t, v) for v, t in first_seen.items() if 0.2 * final <= v < final and int(v) in wall)
        self.assertGreaterEqual(len(steady), 10, f"too few scrapes in the steady run: {steady}")
        (t0, v0), (t1, v1) = steady[0], steady[-1]
        scraped = (v1 - v0) / (t1 - t0)
        csv_rate = (v1 - v0) / (wall[int(v1)] - wall[int(v0)])
        print(f"\nenv steps {int(v0):,} -> {int(v1):,}: Prometheus {scraped:,.0f}/s over {t1 - t0:.2f} s of "
              f"scrapes, metrics.csv {csv_rate:,.0f}/s over {wall[int(v1)] - wall[int(v0)]:.2f} s of wall_seconds "
              f"(ratio {scraped / csv_rate:.4f})", file=sys.stderr)
        self.assertAlmostEqual(scraped / csv_rate, 1.0, delta=0.05)

    def test_the_runs_prometheus_config_is_valid_and_names_every_endpoint(self):
        path = os.path.join(self.run_dir, "prometheus.yml")
        r = subprocess.run(["promtool", "check", "config", path], capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        text = read(path)
        for ports in self.jobs.values():
            for port in ports:
                self.assertIn(f'"127.0.0.1:{port}"', text)

    def test_rpc_calls_are_counted_on_both_sides(self):
        def value(text, name, **labels):
            for f in text_string_to_metric_families(text):
                for s in f.samples:
                    if s.name == name and all(s.labels.get(k) == v for k, v in labels.items()):
                        return s.value
            return None

        learner = self.texts[("learner", self.base + 1)]
        reward = self.texts[("reward_server", self.base)]
        actor = self.texts[("actor", self.base + 2)]
        self.assertGreater(value(learner, "imca_rpc_server_handled_total", method="GetPolicy", code="OK"), 0)
        self.assertGreater(value(reward, "imca_rpc_server_handled_total", method="Score", code="OK"), 0)
        self.assertGreater(value(actor, "imca_rpc_client_handled_total", method="Score", code="OK"), 0)
        self.assertGreater(value(actor, "imca_rpc_client_handling_seconds_count", method="Score"), 0)
        self.assertGreater(value(learner, "imca_learner_policy_lag_versions_count"), 0)


class OneDefinitionTest(unittest.TestCase):
    """Each metric name is spelled in exactly one C++ place, and the tools
    copy no list the binaries can tell them (`--list`)."""

    def test_each_exported_family_is_defined_once_in_cpp(self):
        # The learner's column families, as it reports them, and below every
        # name the sources spell.
        names = {c["prometheus"] for c in binaries.facts()["metrics_columns"] if c["prometheus"]}
        sources = []
        for folder in ("common", "learner", "reward_server", "actor", "envtool"):
            for dirpath, _, files in os.walk(os.path.join(ROOT, folder)):
                sources += [os.path.join(dirpath, f) for f in files
                            if f.endswith((".cc", ".h")) and not f.endswith("_test.cc")]
        text = {path: read(path) for path in sources}
        # Every family name a library or binary spells ("imca_..." or "process_...").
        for body in text.values():
            names.update(re.findall(r'"((?:imca|process)_[a-z0-9_]+)"', body))
        self.assertGreater(len(names), 50)
        for name in sorted(names):
            places = [f"{os.path.relpath(p, ROOT)}" for p, body in text.items() for _ in
                      re.finditer(re.escape(f'"{name}"'), body)]
            self.assertEqual(len(places), 1, f"{name} is spelled in {places}")

    def test_the_tools_copy_no_scenario_reward_credit_or_permutation_list(self):
        known = binaries.facts()
        # A line naming every credit mode (or permutation, reward kind, or
        # most scenarios) is a copy of the list; a grid choosing some is not.
        lists = {"scenario": (known["scenarios"], 4), "reward": (list(known["rewards"]), len(known["rewards"])),
                 "credit": (known["credits"], len(known["credits"])),
                 "permutation": (known["permutations"], len(known["permutations"]))}
        tools = os.path.join(ROOT, "tools")
        sources = sorted(os.path.relpath(os.path.join(folder, f), ROOT) for folder, _, files in os.walk(tools)
                         for f in files if f.endswith(".py"))
        self.assertIn("tools/imca_tools/train.py", sources)
        for name in sources:
            for n, line in enumerate(read(os.path.join(ROOT, name)).splitlines(), 1):
                for what, (values, copied) in lists.items():
                    quoted = [v for v in values if re.search(rf'["\']{re.escape(v)}["\']', line)]
                    self.assertLess(len(quoted), copied, f"{name}:{n} copies the {what} list: {line.strip()}")


if __name__ == "__main__":
    unittest.main(verbosity=2)
