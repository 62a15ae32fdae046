#!/usr/bin/python3
"""Every training default has one home, in C++ (docs/learner.md, "Defaults").

For every scenario: each bare binary started with only --scenario resolves
(`--print_config`) exactly the configuration that ./imca train runs and
records in config.json ("resolved", and the flat settings it shows); and the
deploy manifests pass only what a user overrides: wiring (addresses, files,
secrets, restart behaviour) and ./imca train's options set to something
other than the binary's default. A default re-stated in tools/ or
deploy/, or changed in one home only, fails here.
"""
import json
import os
import subprocess
import sys
import time
import unittest

ROOT = os.environ.get("IMCA_ROOT", os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("IMCA_BIN", os.path.join(ROOT, "build", "bin"))
import deploy_test  # the manifests' services, as its tests read them (tests/, this script's folder)
from imca_tools import binaries, learner_presets, options, plan
from imca_tools.options import dest

# Flags that say where a process runs and how it is wired or supervised, not
# what it trains: a deployment sets them for itself.
WIRING = {
    "reward_server": {"listen", "port_file", "snapshot", "status_file", "signal_exit_code", "journal_fsync", "max_inflight",
                      "max_inflight_per_actor", "max_receive_mb"},
    "learner": {"listen", "port_file", "run_dir", "resume", "auto_resume", "trained_log", "status_file",
                "signal_exit_code", "linger_seconds", "max_streams", "max_receive_mb"},
    # The actor's seed is its own identity (./imca train gives actor i
    # seed * 1000 + i + 1; a deployment's replicas draw theirs with 0).
    "actor": {"learner", "reward_server", "actor_id", "seed", "rpc_timeout_ms", "ack_timeout_ms", "status_file",
              "trace_file", "signal_exit_code"},
}
COMMON_WIRING = {"tls_cert", "tls_key", "tls_ca", "tls_client_auth", "tls_server_name", "token_file",
                 "metrics_listen", "map"}


# ./imca train flag -> {program: the binary's flag}.
PROGRAMS_OF = {flag: programs for flag, programs, _ in options.all_options()}


def print_config(program, flags):
    out = subprocess.run([os.path.join(BIN, program), *flags, "--print_config"], capture_output=True, text=True,
                         timeout=120)
    if out.returncode != 0:
        raise AssertionError(f"{program} {' '.join(flags)} --print_config: {out.stderr.strip()}")
    return json.loads(out.stdout)


def overrides(program):
    """{binary flag: ./imca train flag} of the options a user can override."""
    return {programs[program]: flag for flag, programs, _ in options.all_options() if program in programs}


class OneHomeTest(unittest.TestCase):
    def check_scenario(self, scenario, extra=()):
        args = plan.parse_args(["--scenario", scenario, *extra])
        flags, config = plan.plan(args)
        for program in binaries.PROGRAMS:
            with self.subTest(scenario=scenario, program=program, extra=extra):
                bare = print_config(program, [f"--scenario={scenario}"] + [
                    f"--{PROGRAMS_OF[flag][program]}={value}" for flag, value in zip(extra[::2], extra[1::2])
                    if program in PROGRAMS_OF[flag]])
                self.assertEqual(config["resolved"][program], bare, f"./imca train's {program} is not the bare one")
                # The settings config.json shows are the ones the binary runs.
                for name, flag in overrides(program).items():
                    if name in bare:
                        self.assertEqual(config[options.dest(flag)], bare[name], f"config.json {options.dest(flag)}")

    def test_bare_binaries_resolve_what_imca_train_runs(self):
        for scenario in binaries.facts()["scenarios"]:
            self.check_scenario(scenario)

    def test_the_algorithm_and_reward_kind_defaults_too(self):
        self.check_scenario("spread", ("--algo", "maddpg"))
        self.check_scenario("pass_cmae", ("--algo", "cmae"))
        self.check_scenario("pass", ("--reward", "eiti"))

    def test_list_prints_what_print_config_resolves(self):
        known = binaries.facts()
        for scenario in ("coop_nav", "predator_prey"):
            self.assertEqual(known["learner_defaults"]["mappo"][scenario],
                             print_config("learner", [f"--scenario={scenario}"]))
            self.assertEqual(known["actor_defaults"]["mappo"][scenario],
                             print_config("actor", [f"--scenario={scenario}"]))
        self.assertEqual(known["reward_defaults"]["rnd"]["coop_nav"], print_config("reward_server", ["--reward=rnd"]))
        self.assertEqual(known["reward_defaults"]["edti"]["push_box_cmae"],
                         print_config("reward_server", ["--reward=edti", "--scenario=push_box_cmae"]))
        # CMAE's loop: one actor of one env acting a 300-step episode per version.
        self.assertEqual(known["actor_defaults"]["cmae"]["pass_cmae"],
                         print_config("actor", ["--scenario=pass_cmae", "--algo=cmae"]))
        self.assertEqual(known["learner_defaults"]["cmae"]["pass_cmae"],
                         print_config("learner", ["--scenario=pass_cmae", "--algo=cmae"]))
        cmae = known["learner_defaults"]["cmae"]["pass_cmae"]
        self.assertEqual((cmae["actors"], cmae["batch_steps"], cmae["steps"]), (1, 300, 4_500_000))
        self.assertEqual((known["actor_defaults"]["cmae"]["pass_cmae"]["envs"],
                          known["actor_defaults"]["cmae"]["pass_cmae"]["unroll_length"]), (1, 300))
        # The actor and the learner name the same algorithms.
        self.assertEqual(sorted(known["actor_defaults"]), sorted(known["learner_defaults"]))

    def test_print_config_passed_back_resolves_the_same(self):
        for program in binaries.PROGRAMS:
            first = print_config(program, ["--scenario=coop_nav"])
            flags = [f"--{k}={str(v).lower() if isinstance(v, bool) else v}" for k, v in first.items()]
            self.assertEqual(print_config(program, ["--scenario=coop_nav"] + flags), first, program)

    def test_the_tuned_defaults(self):
        coop = print_config("learner", ["--scenario=coop_nav"])
        self.assertEqual((coop["synchronous"], coop["batch_steps"], coop["separate_optimizers"], coop["lr"]),
                         (True, 2048, True, 1e-3))
        pp = print_config("learner", ["--scenario=predator_prey"])
        self.assertEqual((pp["batch_steps"], pp["separate_optimizers"], pp["lr"]), (1024, False, 5e-4))
        self.assertFalse(print_config("learner", ["--algo=maddpg"])["synchronous"])
        # Each env's share of a synchronous iteration is one unroll: 2 actors x 16 envs x 64 = 2048, x 32 = 1024.
        coop_actor, pass_actor = (print_config("actor", [f"--scenario={s}"]) for s in ("coop_nav", "pass"))
        self.assertEqual((coop_actor["envs"], coop_actor["unroll_length"]), (16, 64))
        self.assertEqual((pass_actor["envs"], pass_actor["unroll_length"]), (16, 32))
        self.assertEqual(print_config("actor", ["--algo=cmae"])["envs"], 1)
        self.assertEqual(print_config("reward_server", [])["beta"], 0.5)
        self.assertEqual(print_config("reward_server", ["--reward=edti"])["credit"], "independent")
        # CMAE's tasks pay +1 where EDTI's pay +1000: every kind's beta at a thousandth (count and edti
        # measured so, docs/learner.md), a flag still wins.
        for scenario in ("pass_cmae", "secret_room_cmae", "push_box_cmae"):
            self.assertEqual(print_config("reward_server", [f"--scenario={scenario}"])["beta"], 5e-4)
            self.assertEqual(print_config("reward_server", [f"--scenario={scenario}", "--reward=edti"])["beta"], 1e-3)
        self.assertEqual(print_config("reward_server", ["--scenario=pass_cmae", "--beta=0.5"])["beta"], 0.5)
        self.assertEqual(print_config("reward_server", ["--scenario=pass_mace"])["beta"], 0.5)


class ManifestsPassOnlyOverridesTest(unittest.TestCase):
    def check(self, services):
        self.check_actor_count(services)
        for service in services.values():
            program = service.binary
            scenario = service.flag("scenario") or binaries.facts()["default_scenario"]
            resolved = print_config(program, [a for a in service.args if a.split("=")[0] in
                                              ("--scenario", "--algo", "--reward")])
            user = overrides(program)
            for arg in service.args:
                name, _, value = arg[2:].partition("=")
                if name in WIRING[program] | COMMON_WIRING:
                    continue
                with self.subTest(service=service.name, flag=name):
                    self.assertIn(name, user, f"{service.name}: --{name} is no option of ./imca train")
                    if name in ("scenario",):
                        continue  # The one choice every deployment states.
                    self.assertIn(name, resolved, f"{service.name}: --{name}")
                    default = resolved[name]
                    given = value if value else "true"
                    same = str(default).lower() == given.lower() if isinstance(default, bool) else (
                        str(default) == given or (isinstance(default, float) and float(given) == default))
                    self.assertFalse(same, f"{service.name} re-states --{name}={given}, the default for {scenario}")

    def check_actor_count(self, services):
        """A synchronous learner waits for the shares of --actors actors: as
        many as the deployment runs, each share a whole number of the
        actors' unrolls (else the learner refuses them at the first policy)."""
        by_binary = deploy_test.by_binary(services)
        learner, actor = by_binary["learner"], by_binary["actor"]

        def settings(service):
            return print_config(service.binary, [a for a in service.args if a[2:].partition("=")[0] not in
                                                 WIRING[service.binary] | COMMON_WIRING])

        resolved = settings(learner)
        if resolved["synchronous"]:
            self.assertEqual(resolved["actors"], actor.replicas,
                             "the learner's --actors is not the number of actor replicas")
            acting = settings(actor)
            unroll = acting["envs"] * acting["unroll_length"]
            self.assertEqual(resolved["batch_steps"] % (resolved["actors"] * unroll), 0,
                             f"each actor's share of the {resolved['batch_steps']}-step batch is not a whole number "
                             f"of its unrolls ({acting['envs']} envs x {acting['unroll_length']} steps)")

    def test_compose(self):
        self.check(deploy_test.load_compose())

    def test_kubernetes(self):
        self.check(deploy_test.k8s_services(deploy_test.load_k8s()[1]))


class LearnerPresetTest(unittest.TestCase):
    """--learner-preset: its options as if given first, the command line's
    winning, every one recorded and resolved by the binaries as stated."""

    def test_the_onpolicy_preset_reaches_the_binaries_and_the_record(self):
        args = plan.parse_args(["--learner-preset", "onpolicy", "--lr", "0.002"])
        flags, config = plan.plan(args)
        self.assertEqual(config["learner_preset"], "onpolicy")
        self.assertEqual(config["lr"], 0.002)  # The command line wins.
        resolved = {program: config["resolved"][program] for program in ("learner", "actor")}
        for flag, value in learner_presets.PRESETS["onpolicy"].items():
            with self.subTest(flag=flag):
                self.assertIn(dest(flag), args.given)
                if flag == "--lr":
                    continue
                for program, binary_flag in PROGRAMS_OF[flag].items():
                    if program not in resolved or binary_flag not in resolved[program]:
                        continue  # The actor's print_config leaves out what the learner decides (algo).
                    got = resolved[program][binary_flag]
                    want = (value == "true") if isinstance(got, bool) else type(got)(value)
                    self.assertEqual(got, want, f"{program} --{binary_flag}")
        self.assertEqual(resolved["learner"]["lr"], 0.002)


class LoadTimeEnvTest(unittest.TestCase):
    """The load-time environment (common/base/load_time_env.h): chosen by
    the build, given by the tools to every binary they start, and set by a
    binary started without it."""

    def test_the_tools_give_it_to_their_children(self):
        chosen = binaries.load_time_env()
        self.assertIn("OMP_WAIT_POLICY", chosen)
        # A tool started without it (ctest sets it for this test) gives it to the binaries it starts.
        env = {k: v for k, v in binaries.module_env().items() if k not in chosen}
        probe = ("import subprocess; from imca_tools import binaries; "
                 "print(subprocess.run(['env'], capture_output=True, text=True).stdout)")
        r = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=60)
        self.assertEqual(r.returncode, 0, r.stderr)
        child = dict(line.split("=", 1) for line in r.stdout.splitlines() if "=" in line)
        for name, value in chosen.items():
            self.assertEqual(child.get(name), value, name)

    def test_a_binary_started_without_it_sets_it_itself(self):
        chosen = binaries.load_time_env()
        env = {k: v for k, v in os.environ.items() if k not in chosen}
        proc = subprocess.Popen([os.path.join(BIN, "reward_server"), "--listen=127.0.0.1:0"], env=env,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            seen = {}
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and seen != chosen:
                with open(f"/proc/{proc.pid}/environ", "rb") as f:  # The re-executed image's, same pid.
                    entries = f.read().decode(errors="replace").split("\0")
                seen = {k: v for k, _, v in (e.partition("=") for e in entries) if k in chosen}
                time.sleep(0.1)
            self.assertEqual(seen, chosen)
            self.assertIsNone(proc.poll())
        finally:
            proc.kill()
            proc.wait()


if __name__ == "__main__":
    unittest.main()
