"""imca.make: E environments of one scenario, batched, EnvPool-shaped.

    env = imca.make("coop_nav", num_envs=64, seed=1)
    obs, info = env.reset()                       # obs [E, n, D] float32
    obs, rew, term, trunc, info = env.step(actions)  # actions [E, n] ints

The reset rule: **auto-reset within the step**, as our actors do (and as
gymnasium's vector envs before 1.0): an env whose episode ends at this step
reports that step's rewards and flags, and comes back already reset, so
`obs[e]` and `info["state"][e]` are the first of its next episode;
`info["final_state"][e]` is the state the episode ended in (featurise it with
`env.observe` / `env.global_state` for a truncation bootstrap). This is not
EnvPool's rule, which spends the next step on the reset.

info (every array has E rows, in env order):
  env_id          [E] int32     0..E-1
  state           [E, K] int32  the compact states now (common/env/env.h)
  global_state    [E, G] float32 the critic's input of those states
  final_state     [E, K] int32  the state each step reached, before any reset
  episode_id      [E] int64     the episode each step belonged to
  elapsed_step    [E] int32     its step count t after the step
  episode_return  [E] float32   team return (sum of rewards / n) of the episode
                                that ended at this step; NaN where none did
  success         [E] bool      that episode ended in success
(reset's info has the first three.)

The environments are the services' C++ scenarios and featuriser
(docs/scenarios.md): a policy trained here acts in the actors, and the
compact states go to the reward server as they are.
"""
import math
import numbers
import os

import numpy as np

from . import _core
from .spaces import Box, Discrete

# The scenario options of every binary (common/env/scenario_flags.cc), with the
# type each takes; None means the scenario's default.
OPTIONS = {
    "map": str,           # --map: a map file (default maps/<scenario>.txt)
    "num_agents": int,    # --num_agents
    "step_limit": int,    # --step_limit
    "success_reward": float,  # --success_reward
    "step_penalty": float,    # --step_penalty
    "view_radius": int,   # --view_radius: see others within r cells (0: all)
    "door_timer": int,    # --door_timer: EDTI's door-open interval
}
MAX_SEED = 2**64 - 1


def scenarios():
    """Names of the scenarios."""
    return list(_core.scenario_names())


def check_int(name, value, low=None, high=None):
    """`value` as an int, or TypeError/ValueError naming `name` (no casts)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name}: expected an int, got {type(value).__name__} {value!r}")
    value = int(value)
    if (low is not None and value < low) or (high is not None and value > high):
        raise ValueError(f"{name}: {value} is not in [{low}, {high if high is not None else 'inf'}]")
    return value


def check_seed(seed, name="seed"):
    return check_int(name, seed, 0, MAX_SEED)


def core_options(options):
    """_core.Options from keyword options, or TypeError naming the bad one."""
    out = _core.Options()
    for key, value in options.items():
        if key not in OPTIONS:
            raise TypeError(f"unknown option {key!r}; the options are: {', '.join(OPTIONS)}")
        if value is None:
            continue
        kind = OPTIONS[key]
        if kind is int:
            value = check_int(key, value, -2**31, 2**31 - 1)
        elif kind is float:
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
                raise TypeError(f"{key}: expected a number, got {type(value).__name__} {value!r}")
            value = float(value)
            if not math.isfinite(value):
                raise ValueError(f"{key}: {value} is not finite")
        else:
            if not isinstance(value, (str, os.PathLike)):
                raise TypeError(f"{key}: expected a path, got {type(value).__name__} {value!r}")
            value = os.fspath(value)
        setattr(out, key, value)
    out.map_dir = os.environ.get("IMCA_MAP_DIR", "")
    return out


def new_core(scenario, num_envs, seed, options):
    if not isinstance(scenario, str):
        raise TypeError(f"scenario: expected a name, got {type(scenario).__name__} {scenario!r}")
    if scenario not in _core.scenario_names():
        raise ValueError(f"scenario: unknown scenario {scenario!r}; the scenarios are: {', '.join(scenarios())}")
    num_envs = check_int("num_envs", num_envs, 1, 1 << 20)
    return _core.Env(scenario, num_envs, check_seed(seed), core_options(options))


class VectorEnv:
    """E environments of one scenario stepped together (see the module doc).

    Not thread-safe: step one instance from one thread at a time (the C++
    part runs without the GIL, so several instances step in parallel).
    """

    def __init__(self, scenario, num_envs=1, seed=0, **options):
        self._core = new_core(scenario, num_envs, seed, options)
        c = self._core
        self.scenario = c.name
        self.num_envs = c.num_envs
        self.num_agents = c.num_agents
        self.num_actions = c.num_actions
        self.obs_dim = c.obs_dim
        self.global_dim = c.global_dim
        self.state_size = c.state_size
        self.step_limit = c.step_limit
        self.fingerprint = c.fingerprint
        self.options = dict(options)
        # One agent's spaces (every agent has the same).
        self.observation_space = Box(0.0, 1.0, (c.obs_dim,), np.float32)
        self.action_space = Discrete(c.num_actions)
        self.state_space = Box(0.0, 1.0, (c.global_dim,), np.float32)

    def reset(self, seed=None, states=None):
        """(obs [E, n, D], info). With `seed`, env e restarts from the stream
        imca._core.env_seed(seed, e); with `states` too ([E, K]), from those
        states. Without, each env's next episode of its stream."""
        if seed is not None:
            seed = check_seed(seed)
        return self._core.reset(seed, states)

    def step(self, actions):
        """(obs, rewards [E, n], terminated [E], truncated [E], info) for
        integer actions [E, n] in [0, num_actions)."""
        return self._core.step(actions)

    def observe(self, states):
        """Observations [..., n, D] of compact states [..., K]."""
        return self._core.observe(states)

    def global_state(self, states):
        """Global states [..., G] (the critic's input) of compact states [..., K]."""
        return self._core.global_state(states)

    def render(self, env_id=0, cell_px=24):
        """An RGB picture [H, W, 3] uint8 of env `env_id`'s current state."""
        env_id = check_int("env_id", env_id, 0, self.num_envs - 1)
        return self._core.render(self._core.states()[env_id], check_int("cell_px", cell_px))

    def close(self):
        pass

    def __len__(self):
        return self.num_envs

    def __repr__(self):
        return f"imca.make({self.scenario!r}, num_envs={self.num_envs}, seed={self._core.seed})"


def make(scenario, num_envs=1, seed=0, **options):
    """A VectorEnv of `num_envs` environments of `scenario` (imca.scenarios()),
    seeded with `seed`; options are the binaries' scenario flags: map,
    num_agents, step_limit, success_reward, step_penalty, view_radius,
    door_timer."""
    return VectorEnv(scenario, num_envs, seed, **options)
