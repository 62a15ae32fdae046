#!/usr/bin/python3
"""deploy/: the docker-compose file and the Kubernetes manifests train for real.

No Docker engine or cluster runs here, so each deployment is checked in two
ways. Statically: every address an actor dials is a Service (or compose
service) that routes to the port its server listens on, probes hit that port,
every state path lies on a mounted volume, and the three services agree on the
scenario. Dynamically: the services are started as local processes with
exactly the deployment's flags, except what only a cluster provides (addresses
become loopback ports, mount paths a temporary folder, the budget a small
one); they must train to the budget and exit cleanly, the reward server must
leave its snapshot, and a restarted learner must continue from its checkpoint.
"""
import os
import re
import shlex
import shutil
import subprocess
import tempfile
import time
import unittest
import urllib.request

import yaml

from imca_tools import binaries, runs, supervisor

ROOT = os.environ.get("IMCA_ROOT", os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("IMCA_BIN", os.path.join(ROOT, "build", "bin"))

os.environ["IMCA_MAP_DIR"] = os.path.join(ROOT, "maps")  # The services' children inherit it.
COMPOSE = os.path.join(ROOT, "deploy", "docker-compose.yml")
K8S_DIR = os.path.join(ROOT, "deploy", "k8s")
BINARIES = ("reward_server", "learner", "actor")
# common/env/scenario_flags.cc: every process must build the same scenario.
SCENARIO_FLAGS = ("scenario", "map", "num_agents", "step_limit", "success_reward", "step_penalty", "view_radius")
# common/rpc/transport_flags.cc: the flags that name secret files.
TLS_FILE_FLAGS = ("tls_cert", "tls_key", "tls_ca", "token_file")


class Service:
    """One process of a deployment: its binary, flags and volume mounts."""

    def __init__(self, name, command, mounts, replicas=1, secrets=(), probes=()):
        self.name = name
        self.binary = os.path.basename(command[0])
        self.args = list(command[1:])
        self.mounts = mounts          # container paths of mounted volumes
        self.replicas = replicas
        self.secrets = list(secrets)  # container paths (files or folders) holding secrets
        self.probes = list(probes)    # probe commands (argv)

    def flag(self, name):
        values = [a.split("=", 1)[1] for a in self.args if a.startswith(f"--{name}=")]
        return values[-1] if values else None


def flags_of(binary):
    """The flag names a binary accepts, from its --helpfull."""
    out = subprocess.run([os.path.join(BIN, binary), "--helpfull"], capture_output=True, text=True, timeout=30)
    return set(re.findall(r"^\s+--([a-z_0-9]+)", out.stdout + out.stderr, re.M))


def load_compose_doc():
    with open(COMPOSE) as f:
        return yaml.safe_load(f)


def check_prometheus_config(path):
    """promtool check config of `path`, with deploy/prometheus/rules.yml
    beside it as the deployments mount it; returns the parsed config."""
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copy(path, os.path.join(tmp, "prometheus.yml"))
        shutil.copy(os.path.join(ROOT, "deploy", "prometheus", "rules.yml"), tmp)
        r = subprocess.run(["promtool", "check", "config", os.path.join(tmp, "prometheus.yml")],
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stdout + r.stderr
    with open(path) as f:
        return yaml.safe_load(f)


def metrics_port(service):
    return int(service.flag("metrics_listen").rsplit(":", 1)[1])


def load_compose():
    doc = load_compose_doc()
    services = {}
    for name, spec in doc["services"].items():
        if spec.get("image") != "imca:latest":
            continue  # Not ours: the prometheus service (ComposeTest checks it apart).
        command = spec["command"]
        command = shlex.split(command) if isinstance(command, str) else command
        mounts = [v.split(":")[1] for v in spec.get("volumes", [])]
        replicas = spec.get("deploy", {}).get("replicas", 1)
        secrets = []
        for secret in spec.get("secrets", []):
            source = secret if isinstance(secret, str) else secret["source"]
            assert source in doc.get("secrets", {}), f"{name}: secret {source} is not defined"
            target = secret if isinstance(secret, str) else secret.get("target", source)
            secrets.append("/run/secrets/" + target)
        services[name] = Service(name, command, mounts, replicas, secrets)
    return services


def load_kustomization(directory):
    with open(os.path.join(directory, "kustomization.yaml")) as f:
        kustomization = yaml.safe_load(f)
    docs = []
    for resource in kustomization["resources"]:
        with open(os.path.join(directory, resource)) as f:
            docs += [d for d in yaml.safe_load_all(f) if d]
    return kustomization, docs


def load_k8s():
    """The workloads' kustomization and the separately applied volumes."""
    kustomization, docs = load_kustomization(K8S_DIR)
    _, volumes = load_kustomization(os.path.join(K8S_DIR, "volumes"))
    return kustomization, docs, volumes


def pod_templates(docs):
    """(workload doc, container) for every container of a Deployment or Job."""
    for doc in docs:
        if doc["kind"] in ("Deployment", "Job"):
            for container in doc["spec"]["template"]["spec"]["containers"]:
                yield doc, container


def k8s_services(docs):
    services = {}
    for doc, c in pod_templates(docs):
        command = c.get("command", []) + c.get("args", [])
        volumes = {v["name"]: v for v in doc["spec"]["template"]["spec"].get("volumes", [])}
        mounts = [m["mountPath"] for m in c.get("volumeMounts", [])]
        secrets = []
        for m in c.get("volumeMounts", []):
            secret = volumes[m["name"]].get("secret")
            if secret is not None:
                items = secret.get("items")
                secrets += [m["mountPath"] + "/" + i["path"] for i in items] if items else [m["mountPath"]]
        probes = [c[p]["exec"]["command"] for p in ("readinessProbe", "livenessProbe") if "exec" in c.get(p, {})]
        replicas = doc["spec"].get("replicas", doc["spec"].get("parallelism", 1))
        services[doc["metadata"]["name"]] = Service(doc["metadata"]["name"], command, mounts, replicas, secrets,
                                                    probes)
    return services


def by_binary(services):
    """{binary: Service}; a deployment runs each binary as one service."""
    return {s.binary: s for s in services.values()}


def read(path):
    with open(path) as f:
        return f.read()


def listen_port(service):
    return int(service.flag("listen").rsplit(":", 1)[1])


def under_mount(path, mounts):
    return any(path == m or path.startswith(m.rstrip("/") + "/") for m in mounts)


class Deployment:
    """A deployment's services as local processes over loopback, started and
    stopped by the launcher's own process handling (imca_tools.supervisor)."""

    def __init__(self, services, tmp):
        self.by_binary = by_binary(services)
        self.tmp = tmp
        self.ports = {}
        self.procs = supervisor.Services(tmp)  # Logs in tmp/logs/<name>.log.
        # The secrets an operator makes with tools/make_certs.sh (client
        # "actor"), where the deployment mounts them.
        folders = {os.path.dirname(s.flag(f)) for s in services.values() for f in TLS_FILE_FLAGS if s.flag(f)}
        for folder in folders:
            subprocess.run([binaries.MAKE_CERTS, tmp + folder, "actor", "probe"], check=True)

    def local_args(self, service, steps):
        """The service's flags with cluster paths, addresses and budget made local."""
        out = []
        for arg in service.args:
            name, _, value = arg[2:].partition("=")
            if name == "listen":
                # A restarted server keeps its address, as behind a Service.
                arg = f"--listen=127.0.0.1:{self.ports.get(service.binary, 0)}"
                out.append(f"--port_file={os.path.join(self.tmp, service.binary + '.port')}")
            elif name in ("learner", "reward_server"):
                arg = f"--{name}=127.0.0.1:{self.ports[name]}"
            elif name == "metrics_listen":
                arg = "--metrics_listen=127.0.0.1:0"  # Every process here shares one address.
            elif name == "steps":
                arg = f"--steps={steps}"
            elif value.startswith("/"):
                arg = f"--{name}={self.tmp}{value}"
            out.append(arg)
        if steps is not None and service.binary == "learner" and not service.flag("steps"):
            out.append(f"--steps={steps}")  # The deployment trains the default budget; here a small one.
        for mount in service.mounts:
            os.makedirs(self.tmp + mount, exist_ok=True)
        return out

    def start(self, name, binary, steps=None):
        """Starts `binary` as process `name` (its log's name); waits until it serves."""
        service = self.by_binary[binary]
        port_file = os.path.join(self.tmp, binary + ".port")
        if os.path.exists(port_file):
            os.remove(port_file)
        proc = self.procs.start(name, [os.path.join(BIN, binary)] + self.local_args(service, steps))
        if service.flag("listen"):
            self.ports[binary] = self.procs.wait_port(name, proc, port_file, timeout=60)
        if service.flag("metrics_listen"):
            self.check_metrics(name)
        return proc

    def check_metrics(self, name):
        """The process serves Prometheus metrics where its log says."""
        deadline = time.time() + 30
        while not (m := re.search(r"metrics on (http://\S+/metrics)", self.log(name))):
            if time.time() > deadline:
                raise AssertionError(f"{name}: no metrics endpoint in its log:\n{self.log(name)}")
            time.sleep(0.1)
        with urllib.request.urlopen(m.group(1), timeout=10) as r:
            text = r.read().decode()
        if "process_resident_memory_bytes" not in text:
            raise AssertionError(f"{name}: {m.group(1)} serves no process metrics:\n{text[:500]}")

    def probe(self, command):
        """Runs a probe command (imca_health) as the kubelet would, made local."""
        argv = [os.path.join(BIN, command[0])]
        for arg in command[1:]:
            name, _, value = arg[2:].partition("=")
            if name == "target":
                binary = next(b for b, s in self.by_binary.items()
                              if s.flag("listen") and value.endswith(":" + s.flag("listen").rsplit(":", 1)[1]))
                arg = f"--target=127.0.0.1:{self.ports[binary]}"
            elif value.startswith("/"):
                arg = f"--{name}={self.tmp}{value}"
            argv.append(arg)
        return subprocess.run(argv + ["--tls_server_name=localhost"], capture_output=True, text=True, timeout=30)

    def stop(self, name):
        """SIGTERM, then the exit code."""
        return self.procs.stop([name], timeout=60)[name]

    def log(self, name):
        return read(os.path.join(self.tmp, "logs", name + ".log"))

    def metrics(self, run_dir):
        return runs.read_metrics(os.path.join(self.tmp + run_dir, "metrics.csv"))


class DeployTestBase:
    """Checks shared by the compose file and the Kubernetes manifests."""

    services = {}

    def test_every_flag_is_one_the_binary_defines(self):
        for s in self.services.values():
            self.assertIn(s.binary, BINARIES, s.name)
            known = flags_of(s.binary)
            for arg in s.args:
                self.assertRegex(arg, r"^--[a-z_0-9]+(=|$)", f"{s.name}: {arg}")
                self.assertIn(arg[2:].split("=")[0], known, f"{s.name}: {arg}")

    def test_services_agree_on_the_scenario_and_keep_state_on_volumes(self):
        for name in SCENARIO_FLAGS:
            values = {s.flag(name) for s in self.services.values()}
            self.assertEqual(len(values), 1, f"--{name} differs between services: {values}")
        for s in self.services.values():
            for name in ("run_dir", "snapshot"):
                if s.flag(name):
                    self.assertTrue(under_mount(s.flag(name), s.mounts), f"{s.name}: --{name} not on a volume")

    def test_every_connection_is_mutual_tls_with_a_token_from_a_secret(self):
        for s in self.services.values():
            for flag in TLS_FILE_FLAGS:
                path = s.flag(flag)
                self.assertTrue(path, f"{s.name}: no --{flag}")
                self.assertTrue(any(path == m or under_mount(path, [m]) for m in s.secrets),
                                f"{s.name}: --{flag}={path} is not in a mounted secret")
            if s.binary != "actor":
                self.assertIn("--tls_client_auth", s.args, s.name)
            # Each process gets only what it needs: never the CA's key, an
            # actor never the servers' key.
            self.assertFalse([p for p in s.secrets if "ca.key" in p or p.endswith("/ca")], s.name)
            if s.binary == "actor":
                self.assertFalse([p for p in s.secrets if p.endswith("server.key")], s.name)

    def test_trains_to_the_budget_and_restarts_from_state(self):
        services = by_binary(self.services)
        learner_flags = services["learner"]
        run_dir = learner_flags.flag("run_dir")
        snapshot = services["reward_server"].flag("snapshot")
        self.assertIn("--auto_resume", learner_flags.args)
        signal_code = int(learner_flags.flag("signal_exit_code") or 0)
        self.assertNotEqual(signal_code, 0, "a learner stopped early must not look finished")
        self.assertEqual(services["actor"].flag("signal_exit_code"), learner_flags.flag("signal_exit_code"))
        with tempfile.TemporaryDirectory() as tmp:
            d = Deployment(self.services, tmp)

            def actors(group):
                names = [f"actor-{group}-{i}" for i in range(services["actor"].replicas)]
                for name in names:
                    d.start(name, "actor")
                return names

            def finish(learner, group):
                # Actors exit 0 once told the budget is done; the lingering
                # learner then exits 0 on SIGTERM, the budget being done.
                for name in group:
                    proc = dict(d.procs.procs)[name]
                    self.assertEqual(proc.wait(timeout=180), 0, d.log(name) + d.log(learner))
                self.assertEqual(d.stop(learner), 0, d.log(learner))

            try:
                d.start("reward_server-0", "reward_server")
                d.start("learner-0", "learner", steps=8192)
                for service in self.services.values():
                    for command in service.probes:
                        r = d.probe(command)
                        self.assertEqual(r.returncode, 0, f"{service.name} probe {command}: {r.stdout}{r.stderr}")
                        self.assertIn("SERVING", r.stdout)
                finish("learner-0", actors(0))
                rows = len(d.metrics(run_dir))
                self.assertGreaterEqual(rows, 2)

                # An eviction mid-run: SIGTERM before the budget exits non-zero
                # (so Kubernetes starts it again) after a checkpoint.
                d.start("learner-1", "learner", steps=10_000_000)
                group = actors(1)
                deadline = time.time() + 120
                while len(d.metrics(run_dir)) < rows + 2:
                    self.assertLess(time.time(), deadline, d.log("learner-1"))
                    time.sleep(0.2)
                self.assertEqual(d.stop("learner-1"), signal_code, d.log("learner-1"))
                self.assertIn("resumed at policy version", d.log("learner-1"))

                # Its replacement resumes while the same actors reconnect.
                metrics = d.metrics(run_dir)
                d.start("learner-2", "learner", steps=int(metrics[-1]["env_steps"]) + 16384)
                finish("learner-2", group)
                self.assertIn("resumed at policy version", d.log("learner-2"))
                self.assertGreater(len(d.metrics(run_dir)), len(metrics))

                # The reward server snapshots on SIGTERM and starts from it.
                self.assertEqual(d.stop("reward_server-0"), 0, d.log("reward_server-0"))
                self.assertGreater(os.path.getsize(tmp + snapshot), 0)
                d.start("reward_server-1", "reward_server")
                self.assertIn("restored from", d.log("reward_server-1"))
                self.assertEqual(d.stop("reward_server-1"), 0, d.log("reward_server-1"))
            finally:
                d.procs.stop(timeout=5)


class ComposeTest(DeployTestBase, unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.services = load_compose()

    def test_actors_dial_the_services_listen_ports(self):
        actor = by_binary(self.services)["actor"]
        for target in ("learner", "reward_server"):
            host, port = actor.flag(target).rsplit(":", 1)
            self.assertIn(host, self.services, f"actor --{target}")
            self.assertEqual(int(port), listen_port(self.services[host]), f"actor --{target}")

    def test_prometheus_scrapes_every_service_where_it_serves_metrics(self):
        prometheus = load_compose_doc()["services"]["prometheus"]
        mounts = dict(v.rsplit(":", 2)[:2] for v in prometheus["volumes"] if v.startswith("./"))
        self.assertEqual(mounts, {"./prometheus/compose.yml": "/etc/prometheus/prometheus.yml",
                                  "./prometheus/rules.yml": "/etc/prometheus/rules.yml"})
        self.assertIn("--config.file=/etc/prometheus/prometheus.yml", prometheus["command"])
        config = check_prometheus_config(os.path.join(ROOT, "deploy", "prometheus", "compose.yml"))
        jobs = {j["job_name"]: j for j in config["scrape_configs"]}
        self.assertEqual(set(jobs), {"reward_server", "learner", "actor"})
        by = by_binary(self.services)
        for job, scrape in jobs.items():
            service = by[job]
            if "static_configs" in scrape:
                targets = [t for c in scrape["static_configs"] for t in c["targets"]]
                self.assertEqual(targets, [f"{service.name}:{metrics_port(service)}"], job)
            else:  # Every replica, through Docker's DNS.
                (sd,) = scrape["dns_sd_configs"]
                self.assertEqual((sd["names"], sd["port"]), ([service.name], metrics_port(service)), job)
            self.assertEqual(service.flag("metrics_listen").rsplit(":", 1)[0], "0.0.0.0", job)


class KubernetesTest(DeployTestBase, unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.kustomization, cls.docs, cls.volumes = load_k8s()
        cls.services = k8s_services(cls.docs)

    def test_actors_dial_services_that_route_to_the_listen_port(self):
        services = {d["metadata"]["name"]: d for d in self.docs if d["kind"] == "Service"}
        actor = next(s for s in self.services.values() if s.binary == "actor")
        for target in ("learner", "reward_server"):
            host, port = actor.flag(target).rsplit(":", 1)
            self.assertIn(host, services, f"actor --{target}: no Service {host}")
            svc = services[host]["spec"]
            ports = [p for p in svc["ports"] if p["port"] == int(port)]
            self.assertEqual(len(ports), 1, f"Service {host} has no port {port}")
            selected = [(doc, c) for doc, c in pod_templates(self.docs)
                        if svc["selector"].items() <= doc["spec"]["template"]["metadata"]["labels"].items()]
            self.assertEqual(len(selected), 1, f"Service {host} selects {len(selected)} workloads")
            doc, container = selected[0]
            target_port = ports[0]["targetPort"]
            container_ports = {p.get("name"): p["containerPort"] for p in container["ports"]}
            if isinstance(target_port, str):
                self.assertIn(target_port, container_ports, f"Service {host}: no container port named so")
            number = container_ports[target_port] if isinstance(target_port, str) else target_port
            self.assertIn(number, container_ports.values())
            self.assertEqual(number, listen_port(self.services[doc["metadata"]["name"]]), host)
            for probe in ("readinessProbe", "livenessProbe"):
                if probe in container:
                    # The kubelet's gRPC probe cannot dial TLS: imca_health does.
                    command = container[probe]["exec"]["command"]
                    self.assertEqual(command[0], "imca_health", f"{host} {probe}")
                    self.assertIn(f"--target=127.0.0.1:{number}", command, f"{host} {probe}")

    def test_prometheus_scrapes_every_workload_where_it_serves_metrics(self):
        config = check_prometheus_config(os.path.join(K8S_DIR, "prometheus-scrape.yml"))
        services = {d["metadata"]["name"]: d for d in self.docs if d["kind"] == "Service"}
        jobs = {j["job_name"]: j for j in config["scrape_configs"]}
        self.assertEqual(set(jobs), {"reward_server", "learner", "actor"})
        for job, scrape in jobs.items():
            (sd,) = scrape["dns_sd_configs"]
            (name,) = sd["names"]
            svc = services[name]["spec"]
            self.assertEqual(svc.get("clusterIP"), "None", f"{name}: not headless (one address, not every pod)")
            selected = [(doc, c) for doc, c in pod_templates(self.docs)
                        if svc["selector"].items() <= doc["spec"]["template"]["metadata"]["labels"].items()]
            self.assertEqual(len(selected), 1, name)
            doc, container = selected[0]
            service = self.services[doc["metadata"]["name"]]
            self.assertEqual(service.binary, job)
            port = metrics_port(service)
            self.assertEqual(service.flag("metrics_listen").rsplit(":", 1)[0], "0.0.0.0", job)
            self.assertEqual(sd["port"], port, job)
            self.assertIn({"name": "metrics", "containerPort": port}, container["ports"], job)
            (svc_port,) = svc["ports"]
            self.assertEqual((svc_port["port"], svc_port["targetPort"]), (port, "metrics"), name)
            annotations = doc["spec"]["template"]["metadata"]["annotations"]
            self.assertEqual(annotations, {"prometheus.io/scrape": "true", "prometheus.io/port": str(port),
                                           "prometheus.io/path": "/metrics", "prometheus.io/job": job}, job)

    def test_workloads_select_their_pods_and_claims_exist(self):
        # The claims live apart so that deleting the workloads keeps the state.
        self.assertFalse([d for d in self.docs if d["kind"] == "PersistentVolumeClaim"])
        claims = {d["metadata"]["name"] for d in self.volumes if d["kind"] == "PersistentVolumeClaim"}
        mounted = []
        images = set()
        for doc in self.docs:
            if doc["kind"] not in ("Deployment", "Job"):
                continue
            spec, pod = doc["spec"], doc["spec"]["template"]["spec"]
            if doc["kind"] == "Deployment":
                self.assertLessEqual(spec["selector"]["matchLabels"].items(),
                                     spec["template"]["metadata"]["labels"].items(), doc["metadata"]["name"])
            else:
                self.assertIn(pod["restartPolicy"], ("OnFailure", "Never"), doc["metadata"]["name"])
                # An evicted pod exits with the signal code: replaced, but not
                # counted towards backoffLimit.
                rules = spec.get("podFailurePolicy", {}).get("rules", [])
                # status is required when kubectl applies a change as a patch (kubernetes#131512).
                self.assertIn({"action": "Ignore",
                               "onPodConditions": [{"type": "DisruptionTarget", "status": "True"}]}, rules,
                              doc["metadata"]["name"])
                if rules:
                    self.assertEqual(pod["restartPolicy"], "Never", "podFailurePolicy needs restartPolicy Never")
            volumes = {v["name"]: v for v in pod.get("volumes", [])}
            for c in pod["containers"]:
                images.add(c["image"])
                self.assertEqual(c.get("imagePullPolicy"), "IfNotPresent", doc["metadata"]["name"])
                for m in c.get("volumeMounts", []):
                    self.assertIn(m["name"], volumes)
                    if "secret" in volumes[m["name"]]:
                        self.assertEqual(volumes[m["name"]]["secret"]["secretName"], "imca-tls")
                        self.assertTrue(m.get("readOnly"), doc["metadata"]["name"])
                        self.assertNotIn("subPath", m, "a subPath mount never sees a rotated secret")
                        continue
                    claim = volumes[m["name"]]["persistentVolumeClaim"]["claimName"]
                    self.assertIn(claim, claims)
                    mounted.append(claim)
        self.assertEqual(images, {i["name"] for i in self.kustomization["images"]})
        # ReadWriteOnce: one workload per claim.
        self.assertEqual(sorted(mounted), sorted(set(mounted)))

    def test_a_refused_actor_fails_the_job_instead_of_being_replaced(self):
        job = next(d for d in self.docs if d["kind"] == "Job"
                   and d["spec"]["template"]["spec"]["containers"][0]["command"] == ["actor"])
        rules = job["spec"]["podFailurePolicy"]["rules"]
        self.assertIn({"action": "FailJob", "onExitCodes": {"containerName": "actor", "operator": "In",
                                                            "values": [binaries.exit_refused()]}}, rules)

    def test_actor_job_has_no_completion_count(self):
        # Work-queue style: the Job ends when the actors exit after the budget,
        # and parallelism can be changed while it runs.
        jobs = [d for d in self.docs if d["kind"] == "Job"
                and d["spec"]["template"]["spec"]["containers"][0]["command"] == ["actor"]]
        self.assertEqual(len(jobs), 1)
        self.assertNotIn("completions", jobs[0]["spec"])

    def test_the_reward_server_is_a_single_writer(self):
        deployments = [d for d in self.docs if d["kind"] == "Deployment"]
        reward = [d for d in deployments
                  if d["spec"]["template"]["spec"]["containers"][0]["command"] == ["reward_server"]]
        self.assertEqual(len(reward), 1)
        self.assertEqual(reward[0]["spec"]["replicas"], 1)
        self.assertEqual(reward[0]["spec"]["strategy"]["type"], "Recreate")


if __name__ == "__main__":
    unittest.main(verbosity=2)
