"""imca.parallel_env: one environment under PettingZoo's ParallelEnv contract.

    env = imca.parallel_env("coop_nav")
    observations, infos = env.reset(seed=1)
    while env.agents:
        actions = {a: env.action_space(a).sample() for a in env.agents}
        observations, rewards, terminations, truncations, infos = env.step(actions)

The agents' semantics, spelled out (what PettingZoo leaves to each env):
  * possible_agents is fixed: "agent_0" .. "agent_{n-1}".
  * agents holds the live agents. Our scenarios end an episode for every
    agent at once (a team success, a failure or the step limit), so after the
    last step every agent is terminated or truncated and agents is []. An
    agent that left never comes back within the episode; reset() brings all.
  * step() takes a dict with an action for exactly each live agent (a missing
    or extra key is a ValueError naming it) and returns five dicts keyed by
    the agents that were live for that step. Stepping with no live agents is
    a RuntimeError: call reset().
  * No auto-reset: the observations of the last step are of the state the
    episode ended in.
  * reset(seed=s) replays exactly; reset() continues the seeded stream.

A true pettingzoo.ParallelEnv subclass when pettingzoo can be imported,
duck-typed otherwise (pettingzoo is not a dependency).
"""
import numpy as np

from . import env as _env
from .spaces import Box, Discrete

try:  # pragma: no cover - only where pettingzoo is installed
    from pettingzoo import ParallelEnv as _Base
except ImportError:
    _Base = object


class ParallelEnv(_Base):
    """A single environment of `scenario`, PettingZoo-style (module doc)."""

    metadata = {"render_modes": ["rgb_array", "ansi"], "name": "imca_v0", "is_parallelizable": True,
                "render_fps": 4}

    def __init__(self, scenario, render_mode=None, seed=0, **options):
        if render_mode not in (None, "rgb_array", "ansi"):
            raise ValueError(f"render_mode: {render_mode!r} is not one of None, 'rgb_array', 'ansi'")
        self._core = _env.new_core(scenario, 1, seed, options)
        self.render_mode = render_mode
        c = self._core
        self.scenario = c.name
        self.metadata = dict(self.metadata, name=f"imca_{c.name}_v0")
        self.possible_agents = [f"agent_{a}" for a in range(c.num_agents)]
        self.agents = []
        self._index = {agent: a for a, agent in enumerate(self.possible_agents)}
        self.observation_spaces = {a: Box(0.0, 1.0, (c.obs_dim,), np.float32) for a in self.possible_agents}
        self.action_spaces = {a: Discrete(c.num_actions) for a in self.possible_agents}
        self.state_space = Box(0.0, 1.0, (c.global_dim,), np.float32)
        self._state = c.states()[0]
        self._actions = np.zeros((1, c.num_agents), np.int32)

    @property
    def num_agents(self):
        return len(self.agents)

    @property
    def max_num_agents(self):
        return len(self.possible_agents)

    def observation_space(self, agent):
        return self.observation_spaces[self._agent(agent)]

    def action_space(self, agent):
        return self.action_spaces[self._agent(agent)]

    def reset(self, seed=None, options=None):
        """(observations, infos), each keyed by every agent."""
        if options is not None and not isinstance(options, dict):
            raise TypeError(f"options: expected a dict or None, got {type(options).__name__}")
        if options:
            raise ValueError(f"options: reset takes no options, got {sorted(options)}; "
                             "scenario options go to imca.parallel_env(...)")
        if seed is not None:
            seed = _env.check_seed(seed)
            for agent in self.possible_agents:  # Spaces sample reproducibly too.
                self.action_spaces[agent].seed(seed + self._index[agent])
        obs, info = self._core.reset(seed)
        self._state = info["state"][0]
        self.agents = list(self.possible_agents)
        return self._per_agent(obs[0]), {a: {} for a in self.agents}

    def step(self, actions):
        """(observations, rewards, terminations, truncations, infos), five dicts
        keyed by the agents live before the step."""
        if not self.agents:
            raise RuntimeError("step: the episode is over (no live agents); call reset()")
        if not isinstance(actions, dict):
            raise TypeError(f"actions: expected a dict agent -> action, got {type(actions).__name__}")
        extra = [a for a in actions if a not in self.agents]
        if extra:
            raise ValueError(f"actions: {extra[0]!r} is not a live agent (live: {self.agents})")
        for agent in self.agents:
            if agent not in actions:
                raise ValueError(f"actions: no action for live agent {agent!r}")
            u = actions[agent]
            if isinstance(u, np.ndarray) and u.shape == ():
                u = u.item() if u.dtype.kind in "iu" else u
            if isinstance(u, (bool, np.bool_)) or not isinstance(u, (int, np.integer)):
                raise TypeError(f"actions[{agent!r}]: expected an int, got {type(u).__name__} {u!r}")
            if not 0 <= int(u) < self._core.num_actions:
                raise ValueError(f"actions[{agent!r}]: {int(u)} is not in [0, {self._core.num_actions})")
            self._actions[0, self._index[agent]] = int(u)
        obs, rewards, terminated, truncated, info = self._core.step(self._actions)
        self._state = info["final_state"][0]  # No auto-reset: the episode's own last state.
        live = self.agents
        done_term, done_trunc = bool(terminated[0]), bool(truncated[0])
        # The core has reset an ended episode; its last observations are of the final state.
        obs = self._core.observe(self._state) if done_term or done_trunc else obs[0]
        observations = {a: obs[self._index[a]] for a in live}
        rew = {a: float(rewards[0, self._index[a]]) for a in live}
        terminations = {a: done_term for a in live}
        truncations = {a: done_trunc for a in live}
        infos = {a: {} for a in live}
        if done_term or done_trunc:
            for a in live:
                infos[a] = {"success": bool(info["success"][0]),
                            "episode_return": float(info["episode_return"][0]),
                            "episode_length": int(info["elapsed_step"][0])}
            self.agents = []
        return observations, rew, terminations, truncations, infos

    def state(self):
        """The global state [G] float32 (the critic's input)."""
        return self._core.global_state(self._state)

    def compact_state(self):
        """The compact state [K] int32 (common/env/env.h; what the reward server scores)."""
        return self._state.copy()

    def render(self):
        """An RGB array [H, W, 3] uint8 of our renderer (render_mode None or
        "rgb_array"), or the text grid ("ansi")."""
        if self.render_mode == "ansi":
            return self._core.text(self._state)
        return self._core.render(self._state)

    def close(self):
        pass

    def _per_agent(self, obs):
        return {a: obs[self._index[a]] for a in self.possible_agents}

    def _agent(self, agent):
        if agent not in self._index:
            raise KeyError(f"agent: {agent!r} is not one of {self.possible_agents}")
        return agent

    def __repr__(self):
        return f"imca.parallel_env({self.scenario!r})"


def parallel_env(scenario, render_mode=None, **options):
    """A ParallelEnv of `scenario` with the binaries' scenario options."""
    return ParallelEnv(scenario, render_mode=render_mode, **options)
