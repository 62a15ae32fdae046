#!/usr/bin/python3
"""./imca train (imca_tools.train, its plan and supervisor) against the real binaries."""
import csv
import hashlib
import json
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
import unittest

ROOT = os.environ.get("IMCA_ROOT", os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from imca_tools import binaries, options, plan, runs, supervisor, train

LAUNCH = binaries.module_argv("train")
SMALL = ["--actors", "2", "--envs-per-actor", "8", "--unroll-length", "32", "--batch-steps", "1024", "--quiet"]


def run(args, timeout=300):
    return subprocess.run(LAUNCH + args, capture_output=True, text=True, timeout=timeout)


class LauncherErrorsTest(unittest.TestCase):
    def test_bad_flag_names_it_in_one_line(self):
        for args, flag in [(["--credit", "bogus"], "--credit"), (["--steps", "-5"], "--steps"),
                           (["--beta", "-1"], "--beta"), (["--no-such-flag"], "--no-such-flag")]:
            r = run(args)
            self.assertEqual(r.returncode, 2, args)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertIn(flag, r.stderr)

    def test_booleans_take_the_bare_form_and_every_listed_setting_is_an_option(self):
        self.assertTrue(plan.parse_args(["--deterministic", "--seed", "3"]).deterministic)
        self.assertFalse(plan.parse_args(["--deterministic=false"]).deterministic)
        self.assertFalse(plan.parse_args(["--layer-norm", "false"]).layer_norm)
        # A setting the learner or reward server lists is an option without being restated in tools/.
        args = plan.parse_args(["--gamma-int", "0.9", "--reward", "rnd", "--rnd-lr", "0.002"])
        self.assertIn("--gamma_int=0.9", options.program_flags(args, "learner"))
        self.assertIn("--rnd_lr=0.002", options.program_flags(args, "reward_server"))
        names = {flag for flag, _, _ in options.all_options()}
        for program, key in options.LISTED.items():
            for row in binaries.facts()[key]:
                self.assertTrue(any(programs.get(program) == row["name"] for _, programs, _ in options.all_options()),
                                f"{program} --{row['name']} is no ./imca train option")
        self.assertEqual(len(names), len(options.all_options()))
        # A setting of another algorithm is refused, naming it.
        r = run(["--algo", "maddpg", "--layer-norm"])
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("--layer-norm", r.stderr)

    def test_flags_take_underscores_as_hyphens(self):
        args = plan.parse_args(["--num_agents", "3", "--scenario=spread", "--door_timer=2", "--batch-steps", "64"])
        self.assertEqual((args.num_agents, args.scenario, args.door_timer, args.batch_steps), (3, "spread", 2, 64))
        self.assertEqual(options.dashed(["--a_b=c_d", "x_y", "--", "--e_f"]), ["--a-b=c_d", "x_y", "--", "--e_f"])
        r = run(["--no_such_flag"])
        self.assertEqual(r.returncode, 2)
        self.assertIn("--no-such-flag", r.stderr)

    def test_missing_map_names_it(self):
        r = run(["--map", "/nonexistent/map.txt"])
        self.assertEqual(r.returncode, 2)
        self.assertIn("--map", r.stderr)
        self.assertIn("/nonexistent/map.txt", r.stderr)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)

    def test_malformed_maps_and_run_folders_are_one_line(self):
        with tempfile.TemporaryDirectory() as out:
            bad_map = os.path.join(out, "latin1.txt")
            with open(bad_map, "wb") as f:
                f.write(b"#####\n#1\xbf2#\n#####\n")
            r = run(["--map", bad_map])
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertIn("latin1.txt:2:3: unknown map character '\\xbf'", r.stderr)
            for text in (b"{not json", b"[1, 2]", b"\xff\xfe"):
                run_dir = os.path.join(out, "run")
                os.makedirs(os.path.join(run_dir, "checkpoints"), exist_ok=True)
                with open(os.path.join(run_dir, "config.json"), "wb") as f:
                    f.write(text)
                r = run(["--resume", run_dir])
                self.assertEqual(r.returncode, 2, (text, r.stderr))
                self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
                self.assertIn("config.json", r.stderr)
                self.assertIn("--resume", r.stderr)

    def test_port_in_use_is_one_line(self):
        with socket.socket() as s, tempfile.TemporaryDirectory() as out:
            s.bind(("127.0.0.1", 0))
            s.listen(1)
            port = s.getsockname()[1]
            r = run(["--reward-port", str(port), "--out", os.path.join(out, "run")] + SMALL, timeout=60)
            self.assertEqual(r.returncode, 2, r.stderr)
            lines = [l for l in r.stderr.splitlines() if l.strip()]
            self.assertEqual(len(lines), 1, r.stderr)
            self.assertIn(f"127.0.0.1:{port}", lines[0])


class LauncherDefaultsTest(unittest.TestCase):
    def test_defaults_are_the_binaries_and_nothing_is_restated(self):
        args = plan.parse_args([])  # coop_nav.
        self.assertEqual((args.sync, args.batch_steps, args.unroll_length, args.separate_optimizers, args.lr),
                         (True, 2048, 64, True, 1e-3))
        self.assertEqual(args.envs_per_actor, 16)
        # Nothing given, nothing passed: each binary resolves its own defaults.
        for program in binaries.PROGRAMS:
            self.assertEqual(options.program_flags(args, program), [], program)
        pp = plan.parse_args(["--scenario", "predator_prey"])
        self.assertEqual((pp.batch_steps, pp.unroll_length, pp.separate_optimizers, pp.lr), (1024, 32, False, 5e-4))
        self.assertEqual(options.program_flags(pp, "actor"), ["--scenario=predator_prey"])
        # A flag given wins over the scenario's default, and is passed on.
        given = plan.parse_args(["--scenario", "predator_prey", "--separate-optimizers", "true"])
        self.assertTrue(given.separate_optimizers)
        self.assertIn("--separate_optimizers=true", options.program_flags(given, "learner"))
        self.assertEqual(plan.parse_args(["--lr", "2e-4"]).lr, 2e-4)
        old = plan.parse_args(["--sync", "false", "--separate-optimizers", "false", "--batch-steps", "8192",
                                 "--unroll-length", "64"])
        self.assertEqual(options.program_flags(old, "learner"),
                         ["--batch_steps=8192", "--separate_optimizers=false", "--synchronous=false"])
        self.assertEqual(options.program_flags(old, "actor"), ["--unroll_length=64"])

    def test_maddpg_acts_asynchronously_and_keeps_old_unrolls(self):
        args = plan.parse_args(["--algo", "maddpg", "--scenario", "spread", "--updates-per-step", "0.02"])
        self.assertFalse(args.sync)
        flags = options.program_flags(args, "learner")
        self.assertIn("--algo=maddpg", flags)
        self.assertIn("--updates_per_step=0.02", flags)
        self.assertFalse(any(f.startswith("--synchronous") for f in flags))
        # Asked for, synchronous collection is kept.
        self.assertTrue(plan.parse_args(["--algo", "maddpg", "--sync", "true"]).sync)
        for bad, flag in [(["--algo", "ppo"], "--algo"),
                          (["--algo", "maddpg", "--scenario", "pass", "--reward", "edti"], "--algo")]:
            r = run(bad)
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertIn(flag, r.stderr)

    def test_cmae_trains_and_resumes_from_its_checkpoint(self):
        args = plan.parse_args(["--algo", "cmae", "--scenario", "pass_cmae"])
        self.assertEqual((args.actors, args.envs_per_actor, args.unroll_length, args.batch_steps, args.steps),
                         (1, 1, 300, 300, 4_500_000))
        self.assertIn("--algo=cmae", options.program_flags(args, "actor"))
        with tempfile.TemporaryDirectory() as out:
            run_dir = os.path.join(out, "run")
            r = run(["--algo", "cmae", "--scenario", "pass_cmae", "--steps", "30000", "--out", run_dir, "--quiet"])
            self.assertEqual(r.returncode, 0, r.stderr)
            rows = runs.read_metrics(os.path.join(run_dir, "metrics.csv"))
            # One episode of 300 steps per version; acting moves to the
            # exploitation tables by episodes / 15000.
            self.assertEqual((rows[-1]["env_steps"], rows[-1]["cmae_episodes"]), ("30000", "100"))
            self.assertAlmostEqual(float(rows[-1]["cmae_exploit_weight"]), 100 / 15000, places=4)
            self.assertGreater(int(rows[-1]["cmae_replay"]), 0)
            self.assertTrue(os.path.isfile(os.path.join(run_dir, "episode.gif")), r.stderr)
            # Resumed, it goes on from the checkpoint's tables and episodes.
            r = run(["--resume", run_dir, "--steps", "45000", "--quiet"])
            self.assertEqual(r.returncode, 0, r.stderr)
            rows = runs.read_metrics(os.path.join(run_dir, "metrics.csv"))
            self.assertEqual((rows[-1]["env_steps"], rows[-1]["cmae_episodes"]), ("45000", "150"))
        # A joint state too large for its tables: one line, before anything starts.
        r = run(["--algo", "cmae", "--scenario", "coop_nav", "--num-agents", "9"])
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn("2^62", r.stderr)

    def test_a_share_that_is_no_whole_number_of_unrolls_ends_the_run_at_once(self):
        # 2048 / 2 actors = 1024 steps each, not a whole number of 24 x 32 unrolls.
        with tempfile.TemporaryDirectory() as out:
            r = run(["--out", os.path.join(out, "run"), "--envs-per-actor", "24", "--quiet"], timeout=120)
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertIn("not a whole number", r.stderr)
            self.assertIn("--envs", r.stderr)
        # A batch that the actors cannot split is refused before anything starts.
        r = run(["--actors", "3"])
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn("--actors", r.stderr)

    def test_eiti_runs_with_its_own_credit_and_scale(self):
        args = plan.parse_args(["--scenario", "pass", "--reward", "eiti"])
        self.assertEqual((args.credit, args.beta, args.eta, args.beta_t), ("independent", 1.0, 10.0, 10.0))
        self.assertEqual(plan.parse_args(["--scenario", "pass", "--door-timer", "0"]).door_timer, 0)
        for bad, flag in [(["--reward", "eiti", "--credit", "imca"], "--credit"),
                          (["--scenario", "pass", "--door-timer", "31"], "--door-timer")]:
            r = run(bad)
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertIn(flag, r.stderr)

    def test_a_run_from_before_the_defaults_changed_resumes_as_it_ran(self):
        with tempfile.TemporaryDirectory() as run_dir:
            os.mkdir(os.path.join(run_dir, "checkpoints"))
            for recorded in ({}, {"separate_optimizers": None}):
                with open(os.path.join(run_dir, "config.json"), "w") as f:
                    json.dump({"batch_steps": 8192, "unroll_length": 64, **recorded}, f)
                args = plan.parse_args(["--resume", run_dir])
                self.assertEqual((args.sync, args.separate_optimizers, args.batch_steps), (False, False, 8192))
            with open(os.path.join(run_dir, "config.json"), "w") as f:
                json.dump({"batch_steps": 2048, "unroll_length": 16, "sync": True, "separate_optimizers": True}, f)
            args = plan.parse_args(["--resume", run_dir])
            self.assertEqual((args.sync, args.separate_optimizers, args.batch_steps), (True, True, 2048))
            # Passed on explicitly: it resumes as it ran, whatever the defaults are now.
            self.assertIn("--batch_steps=2048", options.program_flags(args, "learner"))
            self.assertIn("--unroll_length=16", options.program_flags(args, "actor"))
            # A folder from before --algo trained MAPPO, whatever the command line says.
            self.assertEqual(plan.parse_args(["--resume", run_dir, "--algo", "maddpg"]).algo, "mappo")


class StepsToSuccessTest(unittest.TestCase):
    def test_a_rate_over_a_part_filled_window_does_not_count(self):
        # One early success is a rate of 100% over one episode: not "reached".
        rows = [{"env_steps": "1024", "success_rate": "1.0", "success_episodes": "1"},
                {"env_steps": "2048", "success_rate": "0.5", "success_episodes": "200"},
                {"env_steps": "3072", "success_rate": "0.95", "success_episodes": "200"}]
        self.assertEqual(runs.steps_to(rows, 0.9), 3072)
        self.assertIsNone(runs.steps_to(rows[:2], 0.9))

    def test_runs_without_the_window_column_read_as_before(self):
        rows = [{"env_steps": "1024", "train_success_rate": "0.2"},
                {"env_steps": "2048", "train_success_rate": "0.9"}]
        self.assertEqual(runs.steps_to(rows, 0.9, "train_success_rate"), 2048)


class QuietRunTest(unittest.TestCase):
    """A run that adds no metrics row says why on its progress line: the
    newest line of the newest log (a disk full, a refused connection)."""

    def test_the_progress_line_says_what_the_run_said_last_once_it_goes_quiet(self):
        rows = [{"env_steps": "2048", "env_steps_per_sec": "1000", "success_rate": "0.5", "episode_return": "1",
                 "intrinsic_reward": "0.01", "wall_seconds": "10"},
                {"env_steps": "4096", "env_steps_per_sec": "1000", "success_rate": "0.5", "episode_return": "1",
                 "intrinsic_reward": "0.01", "wall_seconds": "30"}]
        self.assertIsNone(train.quiet_since(rows, last_change=100, now=159))  # Within three iterations (60 s).
        self.assertEqual(train.quiet_since(rows, last_change=100, now=161), 61)
        self.assertEqual(train.quiet_since([], last_change=100, now=131), 31)  # No row yet: 30 s.
        with tempfile.TemporaryDirectory() as run_dir:
            services = supervisor.Services(run_dir)
            self.assertIsNone(services.newest_log_line())
            services.procs = [["reward_server", None], ["learner", None]]
            for name, text, mtime in (("learner", "learner: iteration 2\n", 1000),
                                      ("reward_server", "serving\njournal write: No space left on device\n", 2000)):
                with open(services.log_path(name), "w") as f:
                    f.write(text)
                os.utime(services.log_path(name), (mtime, mtime))
            said = services.newest_log_line()
            self.assertEqual(said, ("reward_server", "journal write: No space left on device"))
            line = train.progress_line(rows[-1], 10_000, 0, (61, said))
            self.assertTrue(line.startswith("steps 4,096/10,000"), line)
            self.assertTrue(line.endswith(" | no new iteration for 1m01s: reward_server says journal write: No space "
                                          "left on device"), line)
            self.assertEqual(train.progress_line(None, 10_000, 0, (31, None)), "starting | no new iteration for 0m31s")
            self.assertNotIn("no new iteration", train.progress_line(rows[-1], 10_000))


class LauncherRunTest(unittest.TestCase):
    def test_short_run_leaves_a_complete_run_folder(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "run")
            r = run(["--steps", "12000", "--out", out] + SMALL)
            self.assertEqual(r.returncode, 0, r.stderr)
            for name in ["config.json", "metrics.csv", "learning_curve.png", "summary.json", "policy.pb",
                         "episode.gif"]:
                self.assertTrue(os.path.exists(os.path.join(out, name)), name)
            with open(os.path.join(out, "metrics.csv")) as f:
                rows = list(csv.DictReader(f))
            self.assertGreaterEqual(len(rows), 2)
            for column in ["env_steps", "wall_seconds", "success_rate", "episode_return", "intrinsic_reward",
                           "success_episodes", "train_success_episodes"]:
                self.assertIn(column, rows[0])
            # The windows fill up as episodes end, never beyond their size.
            fills = [int(r["train_success_episodes"]) for r in rows]
            self.assertEqual(fills, sorted(fills))
            self.assertLessEqual(fills[-1], binaries.facts()["success_window"])
            self.assertGreater(max(float(r["intrinsic_reward"]) for r in rows), 0.0)
            with open(os.path.join(out, "summary.json")) as f:
                summary = json.load(f)
            self.assertGreaterEqual(summary["env_steps"], 12000)
            for key in ["wall_seconds", "env_steps_per_sec", "final_success_rate"]:
                self.assertIn(key, summary)
            self.assertTrue(any(p.endswith(".pt") for p in os.listdir(os.path.join(out, "checkpoints"))))
            with open(os.path.join(out, "logs", "exit_codes.json")) as f:
                codes = json.load(f)
            self.assertEqual(set(codes.values()), {0}, codes)

    def test_secure_run_is_mutual_tls_with_a_token_on_every_connection(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "run")
            r = run(["--secure", "--steps", "8000", "--out", out] + SMALL)
            self.assertEqual(r.returncode, 0, r.stderr)
            for name in ["ca.pem", "server.pem", "server.key", "actor-0.pem", "actor-1.key", "token"]:
                self.assertTrue(os.path.exists(os.path.join(out, "tls", name)), name)
            logs = os.path.join(out, "logs")
            for server in ("reward_server", "learner"):
                with open(os.path.join(logs, server + ".log")) as f:
                    text = f.read()
                self.assertIn("(mutual TLS, token)", text)
                # Each actor is known by its certificate.
                self.assertIn("certificate CN=actor-0", text)
                self.assertIn("certificate CN=actor-1", text)
            with open(os.path.join(out, "summary.json")) as f:
                self.assertGreaterEqual(json.load(f)["env_steps"], 8000)

    def test_a_refused_client_ends_the_run_instead_of_being_restarted(self):
        with tempfile.TemporaryDirectory() as tmp:
            services = supervisor.Services(tmp, max_restarts=5)
            services.start("actor-0", ["/bin/sh", "-c", "echo 'learner refused this client'; exit 3"])
            services.proc("actor-0").wait()
            with self.assertRaises(binaries.LaunchError) as raised:
                services.supervise(["actor-0"])
            self.assertIn("actor-0 was refused by a server (exit 3): learner refused this client", str(raised.exception))
            self.assertEqual(services.restarts["actor-0"], 0)

    def test_interrupt_stops_everything_and_leaves_a_valid_folder(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "run")
            proc = subprocess.Popen(LAUNCH + ["--steps", "100000000", "--out", out] + SMALL,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            deadline = time.time() + 120
            metrics = os.path.join(out, "metrics.csv")
            while time.time() < deadline and not (os.path.exists(metrics) and os.path.getsize(metrics) > 200):
                time.sleep(0.2)
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=120)
            self.assertEqual(proc.returncode, 130, err)
            with open(os.path.join(out, "summary.json")) as f:
                summary = json.load(f)
            self.assertTrue(summary["interrupted"])
            self.assertGreater(summary["env_steps"], 0)
            with open(os.path.join(out, "logs", "exit_codes.json")) as f:
                codes = json.load(f)
            # Each stopped in order by SIGTERM: the reward server exits 0, the
            # learner and the actors 143 (a signal stop, not a finished run),
            # none killed for hanging (-9) or crashed.
            self.assertEqual(codes["reward_server"], 0, codes)
            self.assertEqual({c for n, c in codes.items() if n != "reward_server"}, {143}, codes)
            self.assertTrue(os.path.exists(os.path.join(out, "learning_curve.png")))

            # --resume continues from the checkpoint: steps and versions go on.
            with open(os.path.join(out, "metrics.csv")) as f:
                before = list(csv.DictReader(f))
            budget = int(before[-1]["env_steps"]) + 4096
            r = run(["--resume", out, "--steps", str(budget), "--quiet"])
            self.assertEqual(r.returncode, 0, r.stderr)
            with open(os.path.join(out, "metrics.csv")) as f:
                after = list(csv.DictReader(f))
            self.assertGreater(len(after), len(before))
            self.assertGreater(int(after[len(before)]["env_steps"]), int(before[-1]["env_steps"]))
            self.assertGreater(int(after[len(before)]["policy_version"]), int(before[-1]["policy_version"]))
            self.assertGreaterEqual(int(after[-1]["env_steps"]), budget)

    def test_a_run_and_its_restarts_execute_the_binaries_it_started_with(self):
        # The binaries in a folder of the test's own (IMCA_BIN), so the test
        # can "rebuild" them mid-run: the learner's becomes a program that
        # exits 7 at once. The learner then killed is restarted from the
        # run's copy (RUN/bin) and the run goes on to its budget.
        with tempfile.TemporaryDirectory() as tmp:
            build = os.path.join(tmp, "bin")
            os.makedirs(build)
            for program in binaries.PROGRAMS + ("imca_env",):
                shutil.copy2(binaries.path(program), build)
            env = binaries.module_env(dict(os.environ, IMCA_BIN=build))
            out = os.path.join(tmp, "run")
            proc = subprocess.Popen(LAUNCH + ["--steps", "40000", "--out", out] + SMALL, env=env,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            metrics = os.path.join(out, "metrics.csv")
            deadline = time.time() + 120
            while time.time() < deadline and not (os.path.exists(metrics) and os.path.getsize(metrics) > 200):
                time.sleep(0.2)
            with open(os.path.join(out, "config.json")) as f:
                pinned = json.load(f)["binaries"]
            for program in binaries.PROGRAMS + ("imca_env",):
                with open(os.path.join(build, program), "rb") as f:
                    self.assertEqual(pinned[program], hashlib.file_digest(f, "sha256").hexdigest(), program)
            learner = supervisor.run_processes(out)["learner"]
            self.assertEqual(os.readlink(f"/proc/{learner}/exe"), os.path.join(out, "bin", "learner"))

            broken = os.path.join(build, "learner")
            os.remove(broken)  # As a linker does: a new file in its place.
            with open(broken, "w") as f:
                f.write("#!/bin/sh\nexit 7\n")
            os.chmod(broken, 0o755)
            os.kill(learner, signal.SIGKILL)

            _, err = proc.communicate(timeout=240)
            self.assertEqual(proc.returncode, 0, err)
            with open(os.path.join(out, "summary.json")) as f:
                summary = json.load(f)
            self.assertEqual({name: n for name, n in summary["restarts"].items() if n}, {"learner": 1})
            self.assertGreaterEqual(summary["env_steps"], 40000)
            self.assertEqual(summary["binaries"], pinned)
            self.assertFalse(os.path.exists(os.path.join(out, "bin")), "the run's copy goes when it ends")

            # Resumed on another build (imca_env rebuilt): config.json keeps both.
            shutil.copy2(binaries.path("learner"), build)
            with open(os.path.join(build, "imca_env"), "ab") as f:
                f.write(b"\0")
            r = subprocess.run(LAUNCH + ["--resume", out, "--steps", str(summary["env_steps"] + 4096), "--quiet"],
                               env=env, capture_output=True, text=True, timeout=240)
            self.assertEqual(r.returncode, 0, r.stderr)
            with open(os.path.join(out, "config.json")) as f:
                config = json.load(f)
            self.assertEqual(config["binaries_earlier"], [pinned])
            self.assertNotEqual(config["binaries"]["imca_env"], pinned["imca_env"])
            self.assertEqual(config["binaries"]["learner"], pinned["learner"])

    def test_binaries_that_change_while_a_run_starts_are_refused(self):
        # The flags were checked by one build and another was copied: one
        # line, and nothing of the copy left.
        with tempfile.TemporaryDirectory() as tmp:
            expected = dict(train.binary_digests(binaries.BIN), learner="0" * 64)
            with self.assertRaisesRegex(binaries.LaunchError, "changed while the run started"):
                train.pin_binaries(tmp, expected)
            self.assertEqual(os.listdir(tmp), [])


if __name__ == "__main__":
    unittest.main(verbosity=2)
