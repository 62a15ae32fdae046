"""Fixtures of the Python package's tests: the binaries of this build
($IMCA_BIN, default build/bin) and real servers on loopback."""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("IMCA_BIN", os.path.join(ROOT, "build", "bin"))
sys.path.insert(0, os.path.join(ROOT, "python"))


def binary(name):
    path = os.path.join(BIN, name)
    if not os.path.exists(path):
        pytest.fail(f"{path} is missing: run ./imca build")
    return path


def env_tool(*args, stdin=None):
    """imca_env's stdout lines as JSON objects (each run must succeed)."""
    done = subprocess.run([binary("imca_env"), *args], input=stdin, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, f"imca_env {' '.join(args)}: {done.stderr}"
    return [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]


class Server:
    """A reward server or learner on 127.0.0.1 at a free port."""

    def __init__(self, program, flags, tmp):
        self.port_file = os.path.join(tmp, f"{program}.{len(os.listdir(tmp))}.port")
        self.log = open(self.port_file + ".log", "w")
        self.process = subprocess.Popen(
            [binary(program), "--listen=127.0.0.1:0", f"--port_file={self.port_file}", *flags],
            stdout=self.log, stderr=subprocess.STDOUT)
        deadline = time.time() + 60
        while not (os.path.exists(self.port_file) and open(self.port_file).read().strip()):
            if self.process.poll() is not None or time.time() > deadline:
                self.stop()
                pytest.fail(f"{program} did not start: {open(self.port_file + '.log').read()}")
            time.sleep(0.05)
        self.port = int(open(self.port_file).read())
        self.address = f"127.0.0.1:{self.port}"

    def stop(self):
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(20)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.log.close()


@pytest.fixture
def tmp_dir():
    path = tempfile.mkdtemp(prefix="imca-py-")
    yield path
    shutil.rmtree(path, ignore_errors=True)


@pytest.fixture
def servers(tmp_dir):
    """servers(program, *flags) starts one; all stop at the test's end."""
    started = []

    def start(program, *flags):
        server = Server(program, list(flags), tmp_dir)
        started.append(server)
        return server

    yield start
    for server in started:
        server.stop()


@pytest.fixture(scope="session")
def certs():
    """A CA, server and client certificates and a token (tools/make_certs.sh)."""
    path = tempfile.mkdtemp(prefix="imca-py-certs-")
    subprocess.run(["bash", os.path.join(ROOT, "tools", "make_certs.sh"), path, "trainer"], check=True,
                   capture_output=True)
    yield path
    shutil.rmtree(path, ignore_errors=True)
