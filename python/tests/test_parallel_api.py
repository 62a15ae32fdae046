"""imca.parallel_env against what PettingZoo's parallel_api_test and
parallel_seed_test check (pettingzoo is not installed here, so the checks
are written out), plus our own agent semantics."""
import inspect
import itertools

import numpy as np
import pytest

import imca

SCENARIOS = imca.scenarios()


def parallel_api_check(env, num_cycles=400):
    """PettingZoo's parallel_api_test, check by check."""
    sig = inspect.signature(env.reset)
    assert "seed" in sig.parameters and "options" in sig.parameters, "reset(seed=None, options=None)"
    for agent in env.possible_agents:
        assert env.observation_space(agent) is env.observation_space(agent), "the same space object each call"
        assert env.action_space(agent) is env.action_space(agent), "the same space object each call"
    for _ in range(2):  # MAX_RESETS
        obs, infos = env.reset()
        assert isinstance(obs, dict) and isinstance(infos, dict)
        assert set(obs) == set(env.agents) == set(env.possible_agents)
        assert set(infos) == set(env.agents)
        terminated = {a: False for a in env.agents}
        truncated = {a: False for a in env.agents}
        live = set(env.agents)
        finished = set()
        for _ in range(num_cycles):
            actions = {a: env.action_space(a).sample() for a in env.agents
                       if not terminated.get(a, True) or not truncated.get(a, True)}
            obs, rewards, terminated, truncated, infos = env.step(actions)
            for agent in env.agents:
                assert agent not in finished, "an agent cannot be revived once done"
                live.add(agent)
            for value in (obs, rewards, terminated, truncated, infos):
                assert isinstance(value, dict)
                assert set(value) == live, "keyed by exactly the agents live before the step"
            for agent, o in obs.items():
                assert env.observation_space(agent).contains(o), agent
            for agent, r in rewards.items():
                assert isinstance(r, float)
            assert set(env.agents) <= set(env.possible_agents)
            for agent, done in itertools.chain(terminated.items(), truncated.items()):
                if done:
                    live.discard(agent)
                    finished.add(agent)
            if not env.agents:
                assert finished == set(env.possible_agents)
                break
        else:
            pytest.fail(f"no episode end within {num_cycles} steps")


def parallel_seed_check(make, seed=42, num_cycles=400):
    """PettingZoo's parallel_seed_test: the same seed gives identical
    observations, rewards, flags and infos."""
    env1, env2 = make(), make()
    for env in (env1, env2):
        env.reset(seed=seed)
        for agent in env.possible_agents:
            env.action_space(agent).seed(seed)
    for _ in range(num_cycles):
        if not env1.agents:
            assert not env2.agents
            break
        actions = {a: env1.action_space(a).sample() for a in env1.agents}
        assert actions == {a: env2.action_space(a).sample() for a in env2.agents}
        out1, out2 = env1.step(actions), env2.step(actions)
        for d1, d2 in zip(out1, out2):
            assert d1.keys() == d2.keys()
            for agent in d1:
                if isinstance(d1[agent], np.ndarray):
                    assert np.array_equal(d1[agent], d2[agent])
                else:
                    assert d1[agent] == d2[agent]
    # And a second seeded reset replays the first.
    o1, _ = env1.reset(seed=seed)
    o2, _ = make().reset(seed=seed)
    assert all(np.array_equal(o1[a], o2[a]) for a in o1)


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_parallel_api(scenario):
    parallel_api_check(imca.parallel_env(scenario, step_limit=60))


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_parallel_seed(scenario):
    parallel_seed_check(lambda: imca.parallel_env(scenario, step_limit=60))


def test_agents_leave_together_and_never_come_back():
    env = imca.parallel_env("coop_nav", step_limit=3)
    env.reset(seed=1)
    assert env.agents == env.possible_agents == ["agent_0", "agent_1"]
    team_return = 0.0
    for t in range(3):
        _, rewards, terminations, truncations, infos = env.step({a: 4 for a in env.agents})
        team_return += np.float32(sum(rewards.values()) / 2)
    assert truncations == {"agent_0": True, "agent_1": True} and not any(terminations.values())
    assert env.agents == [] and env.num_agents == 0 and env.max_num_agents == 2
    assert infos["agent_0"] == {"success": False, "episode_return": pytest.approx(team_return, rel=1e-6),
                                "episode_length": 3}
    assert team_return < 0, "three steps of step penalty"
    with pytest.raises(RuntimeError, match="call reset"):
        env.step({})
    assert env.compact_state()[-1] == 3, "no auto-reset: the state the episode ended in"
    env.reset()
    assert env.agents == env.possible_agents


def test_state_render_and_spaces():
    env = imca.parallel_env("multi_room")
    obs, _ = env.reset(seed=2)
    assert env.state().shape == env.state_space.shape and env.state().dtype == np.float32
    assert env.render().ndim == 3 and env.render().shape[2] == 3
    assert "\n" in imca.parallel_env("multi_room", render_mode="ansi").render()
    space = env.observation_space("agent_1")
    assert space.shape == obs["agent_1"].shape and space.dtype == np.float32
    assert env.action_space("agent_0").n == 5
    with pytest.raises(KeyError, match="agent_7"):
        env.observation_space("agent_7")
    with pytest.raises(ValueError, match="render_mode"):
        imca.parallel_env("multi_room", render_mode="human")


@pytest.mark.parametrize("actions, error, words", [
    ({"agent_0": 1}, ValueError, "no action for live agent 'agent_1'"),
    ({"agent_0": 1, "agent_1": 1, "agent_2": 0}, ValueError, "'agent_2' is not a live agent"),
    ({"agent_0": 1, "agent_1": 5}, ValueError, "actions['agent_1']: 5 is not in [0, 5)"),
    ({"agent_0": 1.0, "agent_1": 1}, TypeError, "actions['agent_0']: expected an int, got float"),
    ({"agent_0": True, "agent_1": 1}, TypeError, "expected an int, got bool"),
    ([1, 1], TypeError, "actions: expected a dict"),
])
def test_bad_actions_raise_naming_the_agent_and_step_nothing(actions, error, words):
    env = imca.parallel_env("coop_nav")
    env.reset(seed=1)
    before = env.compact_state()
    with pytest.raises(error) as raised:
        env.step(actions)
    assert words in str(raised.value)
    assert np.array_equal(env.compact_state(), before)


def test_numpy_actions_from_spaces_are_accepted():
    env = imca.parallel_env("pass")
    env.reset(seed=3)
    env.step({a: np.int64(1) for a in env.agents})
    env.step({a: np.array(2) for a in env.agents})
    with pytest.raises(ValueError, match="options: reset takes no options"):
        env.reset(options={"x": 1})
