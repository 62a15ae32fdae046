"""imca.RewardClient and imca.LearnerClient against real servers on
loopback: plaintext, TLS with a token, mutual TLS; results, exactly-once
retries, and refusals."""
import os

import numpy as np
import pytest

import imca

SCENARIO = "coop_nav"


def rollout(env, T, seed):
    """T steps of uniform random actions: states [T+1, E, K], actions, probs,
    next_states, episode_ids, as a trainer collects them."""
    rng = np.random.default_rng(seed)
    _, info = env.reset(seed=seed)
    states, actions, next_states, ids = [info["state"]], [], [], []
    for _ in range(T):
        u = rng.integers(0, env.num_actions, (env.num_envs, env.num_agents))
        _, _, _, _, info = env.step(u)
        actions.append(u)
        states.append(info["state"])
        next_states.append(info["final_state"])
        ids.append(info["episode_id"])
    probs = np.full((T, env.num_envs, env.num_agents, env.num_actions), 1 / env.num_actions, np.float32)
    return np.stack(states), np.stack(actions), probs, np.stack(next_states), np.stack(ids)


def test_score_gives_the_credited_bonus(servers):
    server = servers("reward_server", f"--scenario={SCENARIO}", "--reward=count")
    env = imca.make(SCENARIO, 4, seed=1)
    states, actions, probs, next_states, ids = rollout(env, 8, seed=1)
    with imca.RewardClient(server.address) as client:
        stats = client.stats()
        assert (stats["scenario"], stats["credit"], stats["beta"]) == (SCENARIO, "imca", 0.5)
        result = client.score(states, actions, probs, next_states=next_states, episode_ids=ids, env=env)
        assert result.global_rewards.shape == (8, 4) and result.agent_rewards.shape == (8, 4, 2)
        assert result.influences is None
        np.testing.assert_allclose(result.shares.sum(-1), 1, rtol=1e-5)
        np.testing.assert_allclose(result.agent_rewards, result.shares * result.global_rewards[..., None],
                                   rtol=1e-5)
        assert (result.global_rewards > 0).all() and (result.global_rewards <= 0.5 + 1e-6).all()
        assert client.stats()["transitions_scored"] == 32
        # The same transitions again are less novel: counts grew.
        again = client.score(states, actions, probs, next_states=next_states, episode_ids=ids, dry_run=True)
        assert (again.global_rewards < result.global_rewards).all()
        assert client.stats()["transitions_scored"] == 32, "a dry run updates nothing"


def test_a_retried_score_is_not_counted_twice(servers):
    server = servers("reward_server", f"--scenario={SCENARIO}")
    env = imca.make(SCENARIO, 2, seed=2)
    states, actions, probs, _, _ = rollout(env, 4, seed=2)
    client = imca.RewardClient(server.address)
    first = client.score(states, actions, probs)
    client._sequence -= 1  # What a retry after a lost answer sends: the same incarnation and sequence.
    repeat = client.score(states, actions, probs)
    stats = client.stats()
    assert stats["transitions_scored"] == 8 and stats["requests_repeated"] == 1
    # Answered as the server now scores them (the counts include them once), uncounted:
    assert np.array_equal(repeat.agent_rewards, client.score(states, actions, probs, dry_run=True).agent_rewards)
    assert (repeat.global_rewards < first.global_rewards).all()


def test_a_deterministic_server_takes_each_call_as_its_own_version_unless_told(servers):
    server = servers("reward_server", f"--scenario={SCENARIO}", "--reward=count", "--deterministic")
    env = imca.make(SCENARIO, 2, seed=3)
    states, actions, probs, _, _ = rollout(env, 4, seed=3)
    with imca.RewardClient(server.address) as client:
        first = client.score(states, actions, probs)
        # By default a call is a version of its own: the next one sees its counts.
        second = client.score(states, actions, probs)
        assert (second.global_rewards < first.global_rewards).all()
        # Two calls of one version do not see each other's increments.
        third = client.score(states, actions, probs, policy_version=100)
        fourth = client.score(states, actions, probs, policy_version=100)
        assert np.array_equal(third.agent_rewards, fourth.agent_rewards)
        assert (client.score(states, actions, probs, policy_version=101).global_rewards < fourth.global_rewards).all()
        for bad in (-1, 1.5, True, "3"):
            with pytest.raises(ValueError, match="policy_version"):
                client.score(states, actions, probs, policy_version=bad)


BAD_INPUT = [
    (lambda s, a, p: (s[:-1], a, p), ValueError, "states: expected shape (5, 2, *)"),
    (lambda s, a, p: (s, a.astype(np.float32), p), TypeError, "actions: expected an integer array"),
    (lambda s, a, p: (s, a + 5, p), ValueError, "is not in [0, 5)"),
    (lambda s, a, p: (s, a, p.astype(np.float64)), TypeError, "probs: expected a float32 array"),
    (lambda s, a, p: (s, a, p * 2), ValueError, "sums to 2.000000, not 1"),
    (lambda s, a, p: (s, a, p[:, :, :1]), ValueError, "probs: 1 agents, the server serves 2"),
]


def test_bad_input_is_refused_before_sending(servers):
    server = servers("reward_server", f"--scenario={SCENARIO}")
    env = imca.make(SCENARIO, 2, seed=3)
    states, actions, probs, _, _ = rollout(env, 4, seed=3)
    with imca.RewardClient(server.address) as client:
        for change, error, words in BAD_INPUT:
            with pytest.raises(error) as raised:
                client.score(*change(states, actions, probs))
            assert words in str(raised.value)
        assert client.stats()["transitions_scored"] == 0


def test_the_servers_refusals_come_back_as_service_errors(servers):
    server = servers("reward_server", f"--scenario={SCENARIO}")
    env = imca.make(SCENARIO, 2, seed=4)
    states, actions, probs, _, _ = rollout(env, 2, seed=4)
    client = imca.RewardClient(server.address)
    states[0, 0, 1] = 0  # A wall.
    with pytest.raises(imca.ServiceError) as raised:
        client.score(states, actions, probs)
    assert raised.value.code == "INVALID_ARGUMENT" and "states" in raised.value.details
    with pytest.raises(imca.ServiceError, match="fingerprint"):
        client.score(*rollout(env, 2, seed=4)[:3], env=imca.make(SCENARIO, 1, step_limit=7))
    dead = imca.RewardClient("127.0.0.1:1", retries=0, timeout=2)
    with pytest.raises(imca.ServiceError) as raised:
        dead.stats()
    assert raised.value.code == "UNAVAILABLE"


def test_tls_and_token(servers, certs):
    ca, cert, key, token_file = (os.path.join(certs, f) for f in ("ca.pem", "server.pem", "server.key", "token"))
    server = servers("reward_server", f"--scenario={SCENARIO}", f"--tls_cert={cert}", f"--tls_key={key}",
                     f"--token_file={token_file}")
    env = imca.make(SCENARIO, 2, seed=5)
    states, actions, probs, _, _ = rollout(env, 3, seed=5)
    with imca.RewardClient(server.address, tls=ca, token_file=token_file) as client:
        assert client.score(states, actions, probs).agent_rewards.shape == (3, 2, 2)
    token = open(token_file).read().split()[0]
    with imca.RewardClient(server.address, tls=imca.TlsConfig(ca=ca), token=token) as client:
        assert client.stats()["transitions_scored"] == 6
    with pytest.raises(imca.ServiceError) as raised:
        imca.RewardClient(server.address, tls=ca, retries=0).stats()
    assert raised.value.code == "UNAUTHENTICATED"
    with pytest.raises(imca.ServiceError) as raised:
        imca.RewardClient(server.address, tls=ca, token="x" * 20, retries=0).stats()
    assert raised.value.code == "UNAUTHENTICATED"
    with pytest.raises(imca.ServiceError) as raised:
        imca.RewardClient(server.address, retries=0, timeout=3).stats()  # Plaintext to a TLS server.
    assert raised.value.code == "UNAVAILABLE"
    with pytest.raises(ValueError, match="token: needs tls"):
        imca.RewardClient(server.address, token=token)
    with pytest.raises(ValueError, match="tls.ca: cannot read"):
        imca.RewardClient(server.address, tls="/no/ca.pem")


def test_mutual_tls_learner_client(servers, certs):
    ca, cert, key = (os.path.join(certs, f) for f in ("ca.pem", "server.pem", "server.key"))
    learner = servers("learner", f"--scenario={SCENARIO}", f"--tls_cert={cert}", f"--tls_key={key}",
                      f"--tls_ca={ca}", "--tls_client_auth")
    mine = imca.TlsConfig(ca=ca, cert=os.path.join(certs, "trainer.pem"), key=os.path.join(certs, "trainer.key"),
                          server_name="learner")
    with imca.LearnerClient(learner.address.replace("127.0.0.1", "localhost"), tls=mine) as client:
        assert client.get_policy().version == 0
        assert client.status()["done"] is False
    with pytest.raises(imca.ServiceError) as raised:
        imca.LearnerClient(learner.address, tls=ca, timeout=3).status()  # No client certificate.
    assert raised.value.code == "UNAVAILABLE"
    with pytest.raises(ValueError, match="wait_ms"):
        imca.LearnerClient(learner.address, tls=mine).get_policy(wait_ms=70000)
