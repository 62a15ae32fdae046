"""IMCA from Python (docs/python.md).

  imca.make(scenario, num_envs, seed, **options)  batched numpy environments
  imca.parallel_env(scenario, **options)         PettingZoo's ParallelEnv contract
  imca.RewardClient(address, ...)                the credited bonus of a reward server
  imca.LearnerClient(address, ...)               a learner's policy and status
  imca.load_policy(path)                         a trained policy.pb in numpy

Built by ./imca build (the extension imca._core and the gRPC stubs imca.v1);
importable with PYTHONPATH=<clone>/python.
"""
from .env import VectorEnv, make, scenarios
from .parallel import ParallelEnv, parallel_env
from .policy import Policy, load_policy, policy_from_bytes
from .clients import LearnerClient, RewardClient, ScoreResult, ServiceError, TlsConfig

__all__ = ["VectorEnv", "make", "scenarios", "ParallelEnv", "parallel_env", "Policy", "load_policy",
           "policy_from_bytes", "RewardClient", "LearnerClient", "ScoreResult", "ServiceError", "TlsConfig"]
