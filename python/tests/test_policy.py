"""imca.load_policy's forward pass against the C++ evaluator (imca_env
rollout --json prints its probabilities), for every architecture the
learners export, and the policies real learners publish."""
import numpy as np
import pytest

import imca
from imca.v1 import learner_service_pb2 as pb
from conftest import env_tool

SCENARIO = "coop_nav"


def synthetic(architecture, obs_dim, num_actions, agent_networks, seed, hidden=(32, 24), scale=1.5):
    """A Policy proto in the documented layout with bold random weights."""
    rng = np.random.default_rng(seed)
    proto = pb.Policy(version=7, architecture=pb.Policy.Architecture.Value(architecture.upper()), obs_dim=obs_dim,
                      num_actions=num_actions, agent_networks=agent_networks)

    def add(name, array):
        proto.tensors.add(name=name, shape=list(array.shape), data=array.astype(np.float32).ravel().tolist())

    for k in range(max(1, agent_networks)):
        prefix = "policy." if agent_networks == 0 else f"agent{k}.policy."
        widths = [obs_dim, *hidden, num_actions]
        if architecture == "mlp_tanh_layernorm":
            add(prefix + "input_norm.weight", 1 + 0.3 * rng.standard_normal(obs_dim))
            add(prefix + "input_norm.bias", 0.3 * rng.standard_normal(obs_dim))
        for i in range(len(widths) - 1):
            add(prefix + f"{i}.weight", scale * rng.standard_normal((widths[i + 1], widths[i])) / np.sqrt(widths[i]))
            add(prefix + f"{i}.bias", 0.5 * rng.standard_normal(widths[i + 1]))
            if architecture == "mlp_tanh_layernorm" and i + 2 < len(widths):
                add(prefix + f"{i}.norm.weight", 1 + 0.3 * rng.standard_normal(widths[i + 1]))
                add(prefix + f"{i}.norm.bias", 0.3 * rng.standard_normal(widths[i + 1]))
    return proto


def compare_with_cpp(policy_path, seeds=(1, 2, 3)):
    """Max |numpy - C++| over the states of C++ rollouts."""
    policy = imca.load_policy(policy_path)
    env = imca.make(SCENARIO, 1)
    worst, states = 0.0, 0
    for seed in seeds:
        for line in env_tool("rollout", f"--scenario={SCENARIO}", f"--policy={policy_path}", "--json",
                             f"--seed={seed}"):
            state = [line["z"]] + [a["cell"] for a in line["agents"]] + [line["t"]]
            cpp = np.asarray(line["probs"], np.float64)
            ours = policy(env.observe(np.asarray(state, np.int32)))
            assert ours.shape == cpp.shape and ours.dtype == np.float32
            worst = max(worst, float(np.abs(ours - cpp).max()))
            states += 1
    assert states > 10
    return worst


@pytest.mark.parametrize("architecture, agent_networks", [
    ("mlp_tanh", 0), ("mlp_tanh_layernorm", 0), ("mlp_relu", 0), ("mlp_relu", 2), ("mlp_tanh", 2)])
def test_forward_pass_matches_the_cpp_evaluator(architecture, agent_networks, tmp_path):
    env = imca.make(SCENARIO, 1)
    path = tmp_path / "policy.pb"
    path.write_bytes(synthetic(architecture, env.obs_dim, env.num_actions, agent_networks, seed=3)
                     .SerializeToString())
    assert compare_with_cpp(path) <= 1e-6


@pytest.mark.parametrize("flags, architecture, agent_networks", [
    ((), "mlp_tanh", 0),
    (("--layer_norm",), "mlp_tanh_layernorm", 0),
    (("--layer_norm", "--input_norm=false"), "mlp_tanh_layernorm", 0),
    (("--algo=maddpg",), "mlp_relu", 0),
    (("--algo=maddpg", "--maddpg_share=false"), "mlp_relu", 2),
])
def test_policies_real_learners_publish(flags, architecture, agent_networks, servers, tmp_path):
    learner = servers("learner", f"--scenario={SCENARIO}", *flags)
    with imca.LearnerClient(learner.address) as client:
        policy = client.get_policy()
        assert client.get_policy(min_version=policy.version + 1) is None, "not modified"
        status = client.status()
    assert (policy.architecture, policy.agent_networks) == (architecture, agent_networks)
    assert status["policy_version"] == policy.version and status["env_steps"] == 0
    path = tmp_path / "policy.pb"
    policy.save(path)
    assert compare_with_cpp(path) <= 1e-6


def test_shapes_sampling_and_fit(tmp_path):
    env = imca.make(SCENARIO, 4, seed=1)
    path = tmp_path / "p.pb"
    path.write_bytes(synthetic("mlp_relu", env.obs_dim, env.num_actions, 2, seed=1).SerializeToString())
    policy = imca.load_policy(path)
    obs, _ = env.reset()
    probs = policy(obs)
    assert probs.shape == (4, 2, env.num_actions)
    np.testing.assert_allclose(probs.sum(-1), 1, atol=1e-6)
    actions = policy.sample(obs, np.random.default_rng(0))
    assert actions.shape == (4, 2) and actions.dtype == np.int32
    env.step(actions)
    policy.fits(env)
    with pytest.raises(ValueError, match=r"obs: this policy has one network per agent; expected shape \(\.\.\., 2, "):
        policy(obs[:, 0])
    with pytest.raises(TypeError, match="obs: expected a float32 array"):
        policy(obs.astype(np.float64))
    with pytest.raises(ValueError, match="differs from the scenario's"):
        policy.fits(imca.make("multi_room", 1))
    shared = imca.policy_from_bytes(synthetic("mlp_tanh", env.obs_dim, env.num_actions, 0, seed=2).SerializeToString())
    assert shared(obs[0, 0]).shape == (env.num_actions,) and shared(obs).shape == (4, 2, env.num_actions)


def test_bad_policy_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="path: cannot read"):
        imca.load_policy(tmp_path / "missing.pb")
    junk = tmp_path / "junk.pb"
    junk.write_bytes(b"\xff\xff\xff")
    with pytest.raises(ValueError, match="not a serialized imca.v1.Policy"):
        imca.load_policy(junk)
    proto = synthetic("mlp_tanh", 10, 5, 0, seed=1)
    proto.architecture = 0  # ARCHITECTURE_UNSPECIFIED: e.g. a policy.pb from before the enum.
    with pytest.raises(ValueError, match=r"policy.architecture 0 \(architecture_unspecified\) is not one of "
                                         "mlp_tanh, mlp_tanh_layernorm, mlp_relu"):
        imca.policy_from_bytes(proto.SerializeToString())
    proto.architecture = 4  # TABULAR_Q: CMAE's tables, acted with by actors and imca_env.
    with pytest.raises(ValueError, match="policy.architecture tabular_q: CMAE's Q-tables"):
        imca.policy_from_bytes(proto.SerializeToString())
    proto = synthetic("mlp_tanh", 10, 5, 0, seed=1)
    del proto.tensors[1]
    with pytest.raises(ValueError, match="policy: tensor 'policy.0.bias' is missing"):
        imca.policy_from_bytes(proto.SerializeToString())
    proto = synthetic("mlp_tanh", 10, 4, 0, seed=1)
    proto.num_actions = 5
    with pytest.raises(ValueError, match="output size 4 != num_actions 5"):
        imca.policy_from_bytes(proto.SerializeToString())
