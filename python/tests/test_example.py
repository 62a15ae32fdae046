"""examples/python_mappo.py's first iterations against a real reward server
(a smoke test: it runs and its saved actor plays in the C++ tools; how fast
it learns is ./imca bench python's to measure)."""
import os
import subprocess
import sys

import imca
from conftest import ROOT, env_tool


def test_first_iterations_train_with_the_servers_bonus(servers, tmp_path):
    server = servers("reward_server", "--scenario=coop_nav", "--reward=count")
    saved = tmp_path / "policy.pb"
    done = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "python_mappo.py"),
                           f"--reward_server={server.address}", "--iterations=2", "--envs=16", f"--save={saved}"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    lines = [line for line in done.stdout.splitlines() if line.startswith("iteration")]
    assert len(lines) == 2 and lines[-1].startswith("iteration 2 steps 1024 ")
    with imca.RewardClient(server.address) as client:
        assert client.stats()["transitions_scored"] == 1024, "every transition's bonus came from the server"
    policy = imca.load_policy(saved)
    assert (policy.architecture, policy.version) == ("mlp_tanh", 2)
    assert env_tool("rollout", "--scenario=coop_nav", f"--policy={saved}", "--json")


def test_bad_flags_name_the_flag():
    done = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "python_mappo.py"), "--envs=0"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "--envs: must be >= 1" in done.stderr
