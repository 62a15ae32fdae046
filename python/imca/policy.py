"""imca.load_policy: a trained policy (a learner's policy.pb) in numpy.

    policy = imca.load_policy("runs/<run>/policy.pb")
    probs = policy(obs)          # obs [..., n, D] (or [..., D] if shared) -> [..., A]
    actions = policy.sample(obs, rng)

Every architecture the learner exports (proto/imca/v1/learner_service.proto's
Policy.Architecture, named here in lower case): "mlp_tanh" and
"mlp_tanh_layernorm" (MAPPO, shared), "mlp_relu" (MADDPG, shared or one
network per agent). The forward pass is the C++ evaluator's
(common/protocol/policy_mlp.cc) in float32: probabilities agree to 1e-6. CMAE's
"tabular_q" policies (Q-tables over joint states, not observations) are
refused: actors and `imca_env rollout` act with them (common/protocol/policy_table.h).
"""
import os

import numpy as np

from . import _core  # The tensor names, as the learner spells them (common/protocol/policy_names.h).

LAYER_NORM_EPS = np.float32(1e-5)  # LibTorch's default, as the learner and the C++ evaluator.


def _v1():
    from .v1 import learner_service_pb2
    return learner_service_pb2


# Architectures that are no network of observations.
NOT_NETWORKS = ("tabular_q",)


def architectures():
    """The architectures load_policy evaluates, by name ("mlp_tanh", ...):
    the proto's enum values but the unspecified one and NOT_NETWORKS, in
    lower case."""
    return tuple(name.lower() for name, number in _v1().Policy.Architecture.items()
                 if number != 0 and name.lower() not in NOT_NETWORKS)


class _Net:
    """One MLP: weights [out, in], biases, optional LayerNorms."""

    def __init__(self, tensors, prefix, obs_dim, num_actions, layer_norm):
        def tensor(name, shape_len):
            if name not in tensors:
                raise ValueError(f"policy: tensor {name!r} is missing")
            t = tensors[name]
            if t.ndim != shape_len:
                raise ValueError(f"policy: tensor {name!r} has {t.ndim} dimensions, expected {shape_len}")
            return t

        def norm(names, what, size):
            gain, shift = tensor(names("weight"), 1), tensor(names("bias"), 1)
            if gain.shape != (size,) or shift.shape != (size,):
                raise ValueError(f"policy: LayerNorm {what!r} is not of size {size}")
            return gain, shift

        def layer_name(layer, part):
            return _core.layer_tensor_name(prefix, layer, part)

        def input_norm_name(part):
            return _core.input_norm_tensor_name(prefix, part)

        # The input's LayerNorm is optional: a policy trained without it has none.
        has_input_norm = layer_norm and any(input_norm_name(part) in tensors for part in ("weight", "bias"))
        self.input_norm = norm(input_norm_name, prefix + "input_norm", obs_dim) if has_input_norm else None
        self.weights, self.biases, self.norms = [], [], []
        width, layer = obs_dim, 0
        while layer_name(layer, "weight") in tensors:
            w = tensor(layer_name(layer, "weight"), 2)
            b = tensor(layer_name(layer, "bias"), 1)
            if w.shape[1] != width or b.shape != (w.shape[0],):
                raise ValueError(f"policy: layer {prefix}{layer} is {w.shape} / {b.shape}, "
                                 f"expected inputs of size {width}")
            width = w.shape[0]
            self.weights.append(np.ascontiguousarray(w.T))  # [in, out]: x @ W.T as Eigen does.
            self.biases.append(b)
            if layer_norm and layer_name(layer + 1, "weight") in tensors:
                self.norms.append(norm(lambda part, layer=layer: layer_name(layer, f"norm.{part}"),
                                       f"{prefix}{layer}.norm", width))
            layer += 1
        if not self.weights:
            raise ValueError(f"policy: tensor {layer_name(0, 'weight')!r} is missing")
        if width != num_actions:
            raise ValueError(f"policy: {prefix} output size {width} != num_actions {num_actions}")

    def logits(self, x, relu):
        if self.input_norm is not None:
            x = _layer_norm(x, *self.input_norm)
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            x = x @ w + b
            if i < last:
                x = np.maximum(x, np.float32(0)) if relu else np.tanh(x)
                if self.norms:
                    x = _layer_norm(x, *self.norms[i])
        return x


def _layer_norm(x, gain, shift):
    mean = x.mean(axis=-1, keepdims=True, dtype=np.float32)
    var = np.square(x - mean).mean(axis=-1, keepdims=True, dtype=np.float32)  # Biased, as LibTorch.
    return (x - mean) * (np.float32(1) / np.sqrt(var + LAYER_NORM_EPS)) * gain + shift


def _softmax(logits):
    z = np.exp(logits - logits.max(axis=-1, keepdims=True))
    return z / z.sum(axis=-1, keepdims=True)


class Policy:
    """A policy as numpy arrays; call it on observations for probabilities.

    Attributes: version, architecture, obs_dim, num_actions, agent_networks
    (0: one network shared by every agent; n: network k acts for agent k).
    Thread-safe (nothing is mutated by a call).
    """

    def __init__(self, proto):
        enum = _v1().Policy.Architecture
        architecture = enum.Name(proto.architecture).lower() if proto.architecture in enum.values() else None
        if architecture in NOT_NETWORKS:
            raise ValueError(f"policy.architecture {architecture}: CMAE's Q-tables over joint states, not a network "
                             "of observations; actors and `imca_env rollout` act with them")
        if architecture not in architectures():
            raise ValueError(f"policy.architecture {proto.architecture} ({architecture or 'unknown'}) is not one of "
                             f"{', '.join(architectures())}")
        if proto.obs_dim < 1 or proto.num_actions < 1:
            raise ValueError(f"policy: obs_dim {proto.obs_dim} and num_actions {proto.num_actions} must be >= 1")
        if not 0 <= proto.agent_networks <= 1024:
            raise ValueError(f"policy.agent_networks is {proto.agent_networks}, expected 0 (shared) or 1..1024")
        self._proto = proto
        self.version = proto.version
        self.architecture = architecture
        self.obs_dim = proto.obs_dim
        self.num_actions = proto.num_actions
        self.agent_networks = proto.agent_networks
        self.sync_steps_per_actor = proto.sync_steps_per_actor
        tensors = {}
        for t in proto.tensors:
            data = np.asarray(t.data, dtype=np.float32)
            if int(np.prod(t.shape)) != data.size:
                raise ValueError(f"policy: tensor {t.name!r} has {data.size} values for shape {list(t.shape)}")
            tensors[t.name] = data.reshape(tuple(t.shape))
        self.tensors = tensors
        layer_norm = architecture == "mlp_tanh_layernorm"
        self._relu = architecture == "mlp_relu"
        prefixes = [_core.policy_tensor_prefix(self.agent_networks, k) for k in range(max(self.agent_networks, 1))]
        self._nets = [_Net(tensors, p, self.obs_dim, self.num_actions, layer_norm) for p in prefixes]

    def __call__(self, obs):
        """Action probabilities [..., A] (float32) of observations [..., D];
        with per-agent networks the observations are [..., n, D] and the
        second-last axis is the agent."""
        obs = np.asarray(obs)
        if obs.dtype != np.float32:  # The network runs in float32; no silent cast.
            raise TypeError(f"obs: expected a float32 array (what imca.make returns), got dtype {obs.dtype}")
        if obs.ndim < 1 or obs.shape[-1] != self.obs_dim:
            raise ValueError(f"obs: expected shape (..., {self.obs_dim}), got {obs.shape}")
        if self.agent_networks == 0:
            return _softmax(self._nets[0].logits(obs, self._relu)).astype(np.float32, copy=False)
        n = self.agent_networks
        if obs.ndim < 2 or obs.shape[-2] != n:
            raise ValueError(f"obs: this policy has one network per agent; expected shape (..., {n}, "
                             f"{self.obs_dim}), got {obs.shape}")
        out = np.empty(obs.shape[:-1] + (self.num_actions,), np.float32)
        for k, net in enumerate(self._nets):
            out[..., k, :] = _softmax(net.logits(obs[..., k, :], self._relu))
        return out

    def sample(self, obs, rng):
        """Actions [...] (int32) drawn from the probabilities with numpy
        Generator `rng`, the way an actor draws (the first index whose
        cumulative probability exceeds a uniform draw)."""
        probs = self(obs)
        u = rng.random(probs.shape[:-1] + (1,))
        actions = (np.cumsum(probs, axis=-1, dtype=np.float64) <= u).sum(axis=-1)
        return np.minimum(actions, self.num_actions - 1).astype(np.int32)

    def fits(self, env):
        """Raises ValueError if this policy cannot act in `env` (an imca env)."""
        if self.obs_dim != env.obs_dim or self.num_actions != env.num_actions:
            raise ValueError(f"policy: observation or action size ({self.obs_dim}, {self.num_actions}) differs "
                             f"from the scenario's ({env.obs_dim}, {env.num_actions})")
        n = getattr(env, "num_agents", None)
        if self.agent_networks not in (0, n):
            raise ValueError(f"policy: networks for {self.agent_networks} agents, the scenario has {n}")

    def to_bytes(self):
        """The serialized imca.v1.Policy (what policy.pb holds)."""
        return self._proto.SerializeToString()

    def save(self, path):
        """Writes the policy as a policy.pb (imca_env rollout --policy plays it)."""
        with open(os.fspath(path), "wb") as f:
            f.write(self.to_bytes())

    def __repr__(self):
        return (f"imca.Policy(version={self.version}, architecture={self.architecture!r}, obs_dim={self.obs_dim}, "
                f"num_actions={self.num_actions}, agent_networks={self.agent_networks})")


def policy_from_bytes(data):
    """A Policy from a serialized imca.v1.Policy."""
    proto = _v1().Policy()
    try:
        proto.ParseFromString(bytes(data))
    except Exception as error:  # google.protobuf.message.DecodeError
        raise ValueError(f"policy: not a serialized imca.v1.Policy ({error})") from None
    return Policy(proto)


def load_policy(path):
    """The Policy in file `path` (a learner's policy.pb, or a checkpoint's)."""
    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as error:
        raise FileNotFoundError(f"path: cannot read {path!r}: {error.strerror}") from None
    try:
        return policy_from_bytes(data)
    except ValueError as error:
        raise ValueError(f"{path}: {error}") from None
