#!/usr/bin/python3
"""Every kind of file the launcher and the binaries read, malformed every way
a user's file can be: each is refused with one line that names the file (or
the flag) and what is wrong, with non-printable bytes escaped, and no
traceback. Kinds: maps (./imca train --map, imca_env --map), experiment
grids (./imca experiment --grid), run folders (./imca train --resume: the
folder, its config.json, its checkpoints), policies (imca_env rollout
--policy) and checkpoints (learner --resume)."""
import os
import subprocess
import tempfile
import unittest

from imca_tools import binaries

TRAIN = binaries.module_argv("train")
EXPERIMENT = binaries.module_argv("experiment")

# What a user's file may hold instead of what it should.
MALFORMED = {
    "empty": b"",
    "not utf-8": b"\xbf\xfe\xff\n",
    "nul bytes": b"\x00\x00\x00\x00",
    "binary garbage": bytes(range(256)),
    "text of another kind": b"hello, world\n",
}


def one_line(test, r, *names):
    """`r` failed with one line on stderr naming each of `names`, no traceback,
    every byte of it printable."""
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    test.assertNotEqual(r.returncode, 0, r.stderr)
    test.assertNotIn("Traceback", r.stderr)
    test.assertEqual(len(lines), 1, r.stderr)
    test.assertTrue(lines[0].isprintable(), repr(lines[0]))
    for name in names:
        test.assertIn(name, lines[0])


def run(argv, timeout=120):
    return subprocess.run(argv, capture_output=True, text=True, errors="backslashreplace", timeout=timeout)


class MalformedInputTest(unittest.TestCase):
    def setUp(self):
        self._tmp = tempfile.TemporaryDirectory()
        self.tmp = self._tmp.name

    def tearDown(self):
        self._tmp.cleanup()

    def write(self, name, data):
        path = os.path.join(self.tmp, name)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "wb") as f:
            f.write(data)
        return path

    def test_maps(self):
        cases = dict(MALFORMED)
        cases["ragged rows"] = b"#####\n#1.2#\n###\n"
        cases["no treasure for coop_nav"] = b"#####\n#1.2#\n#####\n"
        cases["unknown character"] = b"#####\n#1?2#\n#####\n"
        for what, data in cases.items():
            path = self.write(f"maps/{what.replace(' ', '_')}.txt", data)
            with self.subTest(what, program="imca_env"):
                one_line(self, run([os.path.join(binaries.BIN, "imca_env"), "render", "--scenario=coop_nav",
                                    f"--map={path}", f"--out={self.tmp}/x.png"]), os.path.basename(path))
            with self.subTest(what, program="./imca train"):
                r = run(TRAIN + ["--map", path, "--out", os.path.join(self.tmp, "run")])
                self.assertEqual(r.returncode, 2, r.stderr)
                one_line(self, r, os.path.basename(path))
        with self.subTest("a folder"):
            one_line(self, run(TRAIN + ["--map", self.tmp, "--out", os.path.join(self.tmp, "run")]), "--map")

    def test_grids(self):
        cases = dict(MALFORMED)
        cases["a list"] = b"[1, 2]"
        cases["entries not a list"] = b'{"entries": {"scenario": "coop_nav"}}'
        cases["an entry of another type"] = b'{"entries": [42]}'
        cases["an unknown key"] = b'{"entries": [{"scenario": "coop_nav", "reward": "count", "credit": "imca", "sede": 1}]}'
        cases["an unknown scenario"] = b'{"entries": [{"scenario": "nope", "reward": "count", "credit": "imca"}]}'
        cases["a bad seed"] = b'{"entries": [{"scenario": "coop_nav", "reward": "count", "credit": "imca", "seed": -1}]}'
        cases["a bad flag value"] = (b'{"entries": [{"scenario": "coop_nav", "reward": "count", "credit": "imca", '
                                     b'"flags": {"batch_steps": "many"}}]}')
        for what, data in cases.items():
            path = self.write(f"grids/{what.replace(' ', '_')}.json", data)
            with self.subTest(what):
                r = run(EXPERIMENT + ["--grid", path, "--out", os.path.join(self.tmp, "out")])
                self.assertEqual(r.returncode, 2, r.stderr)
                one_line(self, r, "imca experiment")
                self.assertFalse(os.path.exists(os.path.join(self.tmp, "out", "cells")), "nothing ran")
        with self.subTest("a folder"):
            one_line(self, run(EXPERIMENT + ["--grid", self.tmp]), "--grid")
        with self.subTest("--report of a folder whose grid.json is malformed"):
            self.write("reported/grid.json", b"\xbf{")
            one_line(self, run(EXPERIMENT + ["--report", os.path.join(self.tmp, "reported")]), "grid.json")

    def test_run_folders(self):
        with self.subTest("missing"):
            one_line(self, run(TRAIN + ["--resume", os.path.join(self.tmp, "none")]), "--resume")
        with self.subTest("a file"):
            one_line(self, run(TRAIN + ["--resume", self.write("plain", b"x")]), "--resume")
        with self.subTest("no config.json"):
            os.makedirs(os.path.join(self.tmp, "bare", "checkpoints"))
            one_line(self, run(TRAIN + ["--resume", os.path.join(self.tmp, "bare")]), "--resume")
        cases = dict(MALFORMED)
        cases["a list"] = b"[1, 2]"
        cases["settings of the wrong type"] = b'{"scenario": 7, "steps": "many"}'
        for what, data in cases.items():
            run_dir = os.path.join(self.tmp, what.replace(" ", "_"))
            self.write(os.path.join(run_dir, "config.json"), data)
            os.makedirs(os.path.join(run_dir, "checkpoints"), exist_ok=True)
            with self.subTest(what):
                r = run(TRAIN + ["--resume", run_dir])
                self.assertEqual(r.returncode, 2, r.stderr)
                one_line(self, r, "--resume")

    def test_policies(self):
        cases = dict(MALFORMED)
        for what, data in cases.items():
            path = self.write(f"policies/{what.replace(' ', '_')}.pb", data)
            with self.subTest(what):
                r = run([os.path.join(binaries.BIN, "imca_env"), "rollout", "--scenario=coop_nav", f"--policy={path}"])
                one_line(self, r, "--policy")
        with self.subTest("a folder"):
            one_line(self, run([os.path.join(binaries.BIN, "imca_env"), "rollout", "--scenario=coop_nav",
                                f"--policy={self.tmp}"]), "--policy")

    def test_checkpoints(self):
        """A learner resumed from a folder whose only checkpoint is malformed
        refuses to start, naming the checkpoint (a damaged newest among good
        ones is skipped: checkpoint_store_test)."""
        for what, (meta, state) in {
            "meta not text format": (b"\xbf\x00 version: {", b""),
            "state of garbage": (b"version: 4\n", bytes(range(256))),
            "empty state": (b"version: 4\n", b""),
        }.items():
            folder = os.path.join(self.tmp, what.replace(" ", "_"))
            self.write(os.path.join(folder, "ckpt-00000004.meta"), meta)
            self.write(os.path.join(folder, "ckpt-00000004.pt"), state)
            with self.subTest(what):
                r = run([os.path.join(binaries.BIN, "learner"), f"--resume={folder}", "--listen=127.0.0.1:0",
                         f"--run_dir={os.path.join(folder, 'run')}"])
                one_line(self, r, "--resume", "ckpt-00000004")


if __name__ == "__main__":
    unittest.main()
