"""imca.make against the C++ env tool, the reset rule, and bad input."""
import numpy as np
import pytest

import imca
from imca import _core
from conftest import env_tool

SCENARIOS = imca.scenarios()


def tool_state(line):
    """The compact state [z, agent cells, npc cells, t] of an imca_env JSON line."""
    return [line["z"]] + [a["cell"] for a in line["agents"]] + [p["cell"] for p in line["npcs"]] + [line["t"]]


def test_every_scenario_is_offered():
    assert {"coop_nav", "multi_room", "pass", "predator_prey", "secret_room", "twin_buttons"} <= set(SCENARIOS)


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_reset_draws_what_the_env_tool_draws(scenario):
    env = imca.make(scenario, num_envs=3, seed=11)
    _, info = env.reset(seed=11)
    for e in range(3):
        first = env_tool("script", f"--scenario={scenario}", f"--seed={_core.env_seed(11, e)}", "--actions=-",
                         "--json", stdin="")[0]
        assert info["state"][e].tolist() == tool_state(first), e


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_scripted_episodes_match_the_env_tool_bit_for_bit(scenario, tmp_path):
    """Same states, rewards and flags at every step of whole episodes."""
    E, seed = 4, 5
    env = imca.make(scenario, num_envs=E, seed=seed)
    _, info = env.reset(seed=seed)
    start = info["state"].copy()
    rng = np.random.default_rng(7)
    steps = env.step_limit + 2
    script = rng.integers(0, env.num_actions, (steps, E, env.num_agents)).astype(np.int32)
    _, info = env.reset(seed=seed, states=start)  # Env e restarts from Rng(env_seed(seed, e)) in state start[e].
    ours = []
    for t in range(steps):
        _, rewards, terminated, truncated, info = env.step(script[t])
        ours.append((rewards.copy(), terminated.copy(), truncated.copy(), info["final_state"].copy(),
                     info["success"].copy()))
    for e in range(E):
        path = tmp_path / f"actions{e}.txt"
        path.write_text("\n".join(" ".join(map(str, script[t, e])) for t in range(steps)) + "\n")
        lines = env_tool("script", f"--scenario={scenario}", f"--seed={_core.env_seed(seed, e)}",
                         f"--state={','.join(map(str, start[e]))}", f"--actions={path}", "--json")
        assert tool_state(lines[0]) == start[e].tolist()
        assert len(lines) >= 2
        for t, line in enumerate(lines[1:]):
            rewards, terminated, truncated, reached, success = (x[e] for x in ours[t])
            assert tool_state(line) == reached.tolist(), (e, t)
            assert np.array_equal(np.asarray(line["rewards"], np.float32).view(np.int32),
                                  rewards.view(np.int32)), (e, t)
            assert (line["terminated"], line["truncated"], line["success"]) == (terminated, truncated, success)
        last = len(lines) - 2
        assert ours[last][1][e] or ours[last][2][e], "the tool's episode ended where ours did"


@pytest.mark.parametrize("scenario", ["predator_prey", "coop_nav"])
def test_a_seeded_reset_plays_the_env_tools_episode_step_for_step(scenario, tmp_path):
    """reset(seed=s) and imca_env --seed env_seed(s, e): one stream, the
    reset's draws and then the steps' (the prey's moves, contested cells)."""
    E, seed = 3, 9
    env = imca.make(scenario, num_envs=E, seed=seed)
    _, info = env.reset(seed=seed)
    start = info["state"].copy()
    rng = np.random.default_rng(3)
    script = rng.integers(0, env.num_actions, (40, E, env.num_agents)).astype(np.int32)
    reached = []
    for t in range(len(script)):
        _, _, terminated, truncated, info = env.step(script[t])
        reached.append(info["final_state"].copy())
        if (terminated | truncated).any():
            break
    for e in range(E):
        path = tmp_path / f"actions{e}.txt"
        path.write_text("\n".join(" ".join(map(str, script[t, e])) for t in range(len(reached))) + "\n")
        lines = env_tool("script", f"--scenario={scenario}", f"--seed={_core.env_seed(seed, e)}", f"--actions={path}",
                         "--json")
        assert tool_state(lines[0]) == start[e].tolist()
        for t, line in enumerate(lines[1:len(reached) + 1]):
            assert tool_state(line) == reached[t][e].tolist(), (e, t)


def test_auto_reset_within_the_step():
    env = imca.make("coop_nav", num_envs=2, seed=3, step_limit=5)
    obs, info = env.reset(seed=3)
    ids = None
    for t in range(5):
        prev_ids = ids
        obs, rewards, terminated, truncated, info = env.step(np.full((2, env.num_agents), 4))
        ids = info["episode_id"]
    assert truncated.all() and not terminated.any()
    assert (info["elapsed_step"] == 5).all()
    assert (info["final_state"][:, -1] == 5).all(), "final_state is the state the episode ended in"
    assert (info["state"][:, -1] == 0).all(), "the env is already reset"
    assert np.array_equal(obs, env.observe(info["state"])), "obs are of the next episode's first state"
    assert np.array_equal(info["global_state"], env.global_state(info["state"]))
    assert np.isfinite(info["episode_return"]).all()
    np.testing.assert_allclose(info["episode_return"], 5 * env.num_agents * rewards.mean(axis=1) / env.num_agents)
    _, _, _, _, info = env.step(np.zeros((2, env.num_agents), np.int64))
    assert (info["episode_id"] != ids).all(), "a new episode id after the reset"
    assert np.isnan(info["episode_return"]).all(), "no episode ended at this step"


def test_same_seed_same_episodes_and_reset_continues_the_stream():
    a, b = imca.make("predator_prey", 8, seed=9), imca.make("predator_prey", 8, seed=9)
    rng = np.random.default_rng(0)
    oa, _ = a.reset(seed=9)
    ob, _ = b.reset(seed=9)
    assert np.array_equal(oa, ob)
    for _ in range(60):
        u = rng.integers(0, a.num_actions, (8, a.num_agents))
        ra, rb = a.step(u), b.step(u)
        for x, y in zip(ra[:4], rb[:4]):
            assert np.array_equal(x, y)
    s1 = a.reset()[1]["state"]
    s2 = a.reset()[1]["state"]
    assert not np.array_equal(s1, s2), "reset() without a seed draws the next episodes"
    assert np.array_equal(a.reset(seed=9)[1]["state"], imca.make("predator_prey", 8, seed=9).reset()[1]["state"])


def test_observations_are_the_featurizers():
    env = imca.make("coop_nav", 2, seed=1)
    obs, info = env.reset()
    n, H, W = env.num_agents, env._core.height, env._core.width
    state = info["state"][0]
    for a in range(n):
        o = obs[0, a]
        cell = state[1 + a]
        assert o[cell // W] == 1 and o[H + cell % W] == 1 and o[:H + W].sum() == 2
        assert o[env.obs_dim - 1 - n + a] == 1  # Agent id one-hot before t / step_limit.
    assert obs.dtype == np.float32 and obs.shape == (2, n, env.obs_dim) and obs.flags.c_contiguous


@pytest.mark.parametrize("actions, error, words", [
    (np.zeros((4, 2)), TypeError, "actions: expected an integer array, got dtype float64"),
    (np.zeros((4, 2), bool), TypeError, "actions: expected an integer array, got dtype bool"),
    (np.zeros((3, 2), np.int32), ValueError, "actions: expected shape (4, 2), got (3, 2)"),
    (np.zeros(8, np.int32), ValueError, "actions: expected shape (4, 2), got (8,)"),
    (np.full((4, 2), 5, np.int64), ValueError, "actions[0, 0] = 5 is not in [0, 5)"),
    (np.array([[0, 0]] * 3 + [[0, -1]], np.int8), ValueError, "actions[3, 1] = -1 is not in [0, 5)"),
    (np.full((4, 2), 2**63, np.uint64), ValueError, "is not in [0, 5)"),
    ("up", TypeError, "actions: expected an integer array"),
])
def test_bad_actions_raise_naming_the_argument_and_step_nothing(actions, error, words):
    env = imca.make("coop_nav", 4, seed=1)
    _, before = env.reset(seed=1)
    with pytest.raises(error) as raised:
        env.step(actions)
    assert words in str(raised.value)
    assert np.array_equal(env._core.states(), before["state"]), "nothing stepped"


def test_actions_of_any_integer_type_and_layout_step_alike():
    u = np.random.default_rng(1).integers(0, 5, (16, 2))
    results = []
    for actions in (u.astype(np.int32), u.astype(np.int64), u.astype(np.uint8), u.tolist(),
                    np.asfortranarray(u), np.repeat(u, 2, axis=1)[:, ::2]):
        env = imca.make("coop_nav", 16, seed=2)
        results.append(env.step(actions))
    for r in results[1:]:
        for x, y in zip(r[:4], results[0][:4]):
            assert np.array_equal(x, y)


@pytest.mark.parametrize("call, error, words", [
    (lambda: imca.make("no_such"), ValueError, "scenario: unknown scenario 'no_such'; the scenarios are: "),
    (lambda: imca.make(3), TypeError, "scenario: expected a name"),
    (lambda: imca.make("coop_nav", 0), ValueError, "num_envs: 0 is not in [1,"),
    (lambda: imca.make("coop_nav", 2.0), TypeError, "num_envs: expected an int, got float"),
    (lambda: imca.make("coop_nav", 1, seed=-1), ValueError, "seed: -1 is not in [0,"),
    (lambda: imca.make("coop_nav", 1, agents=3), TypeError, "unknown option 'agents'"),
    (lambda: imca.make("coop_nav", 1, num_agents="3"), TypeError, "num_agents: expected an int, got str"),
    (lambda: imca.make("coop_nav", 1, step_limit=True), TypeError, "step_limit: expected an int, got bool"),
    (lambda: imca.make("coop_nav", 1, step_limit=-4), ValueError, "step"),
    (lambda: imca.make("coop_nav", 1, success_reward=float("nan")), ValueError, "success_reward: nan is not finite"),
    (lambda: imca.make("coop_nav", 1, door_timer=3), ValueError, "door"),
    (lambda: imca.make("multi_room", 1, door_timer=31), ValueError, "door"),
    (lambda: imca.make("coop_nav", 1, map="/no/such/map.txt"), ValueError, "/no/such/map.txt"),
    (lambda: imca.make("coop_nav", 1, num_agents=40), ValueError, "agent"),
    (lambda: imca.make("coop_nav", 1, num_agents=-1), ValueError, "num_agents -1 is negative"),
])
def test_bad_construction_raises_naming_the_argument(call, error, words):
    with pytest.raises(error) as raised:
        call()
    assert words in str(raised.value)


def test_bad_states_raise_naming_the_argument():
    env = imca.make("coop_nav", 2, seed=1)
    _, info = env.reset()
    with pytest.raises(ValueError, match="states: needs a seed"):
        env.reset(states=info["state"])
    with pytest.raises(ValueError, match=r"states: expected shape \(2, 4\), got \(1, 4\)"):
        env.reset(seed=1, states=info["state"][:1])
    wall = info["state"].copy()
    wall[1, 1] = 0  # Cell 0 is a wall on every bundled map.
    with pytest.raises(ValueError, match="states: state 1"):
        env.reset(seed=1, states=wall)
    with pytest.raises(TypeError, match="states: expected an integer array"):
        env.observe(info["state"].astype(np.float32))
    with pytest.raises(ValueError, match="states: expected shape"):
        env.observe(info["state"][:, :3])


def test_scenario_options_reach_the_core(tmp_path):
    env = imca.make("predator_prey", 1, num_agents=3, step_limit=17, view_radius=2)
    assert (env.num_agents, env.step_limit, env._core.view_radius) == (3, 17, 2)
    assert imca.make("pass", 1, door_timer=3)._core.door_timer == 3
    plain = imca.make("coop_nav", 1)
    cheap = imca.make("coop_nav", 1, step_penalty=0.5, success_reward=2.0)
    assert plain.fingerprint != cheap.fingerprint
    _, r, _, _, _ = cheap.step([[4, 4]])
    assert r.tolist() == [[-0.5, -0.5]]
    import shutil
    from imca import _core as core
    mine = tmp_path / "mine.txt"
    shutil.copy(f"{core.default_map_dir()}/coop_nav.txt", mine)
    assert imca.make("coop_nav", 1, map=str(mine)).fingerprint == plain.fingerprint


def test_render_is_an_rgb_array():
    env = imca.make("multi_room", 2, seed=1)
    picture = env.render(1, cell_px=8)
    assert picture.dtype == np.uint8 and picture.shape == (env._core.height * 8, env._core.width * 8, 3)
    assert len(np.unique(picture.reshape(-1, 3), axis=0)) > 3
    with pytest.raises(ValueError, match="env_id"):
        env.render(2)
    with pytest.raises(ValueError, match="cell_px"):
        env.render(0, cell_px=1)
