"""Clients of the services: imca.RewardClient and imca.LearnerClient.

    bonus = imca.RewardClient("localhost:50051")
    result = bonus.score(states, actions, probs)   # numpy in, numpy out
    result.agent_rewards                           # [T, E, n] credited r_i^a

On the gRPC stubs generated from proto/imca/v1 (imca.v1) with Debian's
grpcio, with the C++ clients' transport options (docs/security.md): TLS
against a CA (`tls=`), a client certificate for mutual TLS, another server
name than the dialled host, and a bearer token (which needs TLS, as in the
C++ clients).
"""
import collections
import dataclasses
import os
import random
import time

import numpy as np

from . import env as _env


def _grpc():
    import grpc
    return grpc


def _v1():
    from .v1 import learner_service_pb2, learner_service_pb2_grpc, reward_service_pb2, reward_service_pb2_grpc
    return learner_service_pb2, learner_service_pb2_grpc, reward_service_pb2, reward_service_pb2_grpc


class ServiceError(RuntimeError):
    """A call the service refused or could not serve: `code` is the gRPC
    status code name ("INVALID_ARGUMENT", "UNAVAILABLE", ...), `details` the
    server's message (an INVALID_ARGUMENT's names the field)."""

    def __init__(self, method, code, details):
        super().__init__(f"{method}: {code}: {details}")
        self.method, self.code, self.details = method, code, details


@dataclasses.dataclass(frozen=True)
class TlsConfig:
    """The C++ clients' --tls_ca, --tls_cert, --tls_key and --tls_server_name."""
    ca: str
    cert: str = None
    key: str = None
    server_name: str = None


def _read(path, what):
    try:
        with open(os.fspath(path), "rb") as f:
            return f.read()
    except OSError as error:
        raise ValueError(f"{what}: cannot read {os.fspath(path)!r}: {error.strerror}") from None


def _first_token(token_file):
    text = _read(token_file, "token_file").decode("ascii", "replace")
    for line in text.splitlines():
        if line.strip():
            return line.strip()
    raise ValueError(f"token_file: {token_file!r} holds no token")


def _channel(address, tls, token, token_file, options=()):
    grpc = _grpc()
    if not isinstance(address, str) or not address:
        raise TypeError(f"address: expected 'host:port', got {address!r}")
    if isinstance(tls, (str, os.PathLike)):
        tls = TlsConfig(ca=os.fspath(tls))
    if tls is not None and not isinstance(tls, TlsConfig):
        raise TypeError(f"tls: expected None, a CA file or an imca.TlsConfig, got {type(tls).__name__}")
    if token is not None and token_file is not None:
        raise ValueError("token, token_file: give one of them")
    if token_file is not None:
        token = _first_token(token_file)
    if token is not None:
        if not isinstance(token, str) or not 16 <= len(token) <= 4096 or any(c.isspace() for c in token):
            raise ValueError("token: expected 16-4096 printable characters without spaces")
        if tls is None:
            raise ValueError("token: needs tls (gRPC sends tokens only over TLS; docs/security.md)")
    options = list(options) + [("grpc.max_receive_message_length", 64 << 20),
                               ("grpc.max_send_message_length", 64 << 20)]
    if tls is None:
        return grpc.insecure_channel(address, options=options), False
    if (tls.cert is None) != (tls.key is None):
        raise ValueError("tls: cert and key go together (a client certificate for mutual TLS)")
    credentials = grpc.ssl_channel_credentials(
        root_certificates=_read(tls.ca, "tls.ca"),
        private_key=_read(tls.key, "tls.key") if tls.key else None,
        certificate_chain=_read(tls.cert, "tls.cert") if tls.cert else None)
    if token is not None:
        credentials = grpc.composite_channel_credentials(credentials, grpc.access_token_call_credentials(token))
    if tls.server_name:
        options.append(("grpc.ssl_target_name_override", tls.server_name))
    return grpc.secure_channel(address, credentials, options=options), True


class _Client:
    def __init__(self, address, tls=None, token=None, token_file=None, timeout=30.0):
        if not isinstance(timeout, (int, float)) or isinstance(timeout, bool) or timeout <= 0:
            raise ValueError(f"timeout: expected seconds > 0, got {timeout!r}")
        self.address = address
        self.timeout = float(timeout)
        self._channel, self.tls = _channel(address, tls, token, token_file)

    def _call(self, method, rpc, request, timeout=None):
        grpc = _grpc()
        try:
            return rpc(request, timeout=timeout or self.timeout)
        except grpc.RpcError as error:
            raise ServiceError(method, error.code().name, error.details()) from None

    def close(self):
        self._channel.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


ScoreResult = collections.namedtuple(
    "ScoreResult", ["global_rewards", "contributions", "shares", "agent_rewards", "influences"])
ScoreResult.__doc__ = """The reward server's answer for T steps of E envs:
    global_rewards [T, E]     R_i, the global bonus (beta * novelty)
    contributions  [T, E, n]  r^a (count, RND) or d^a (SF), each agent's counterfactual contribution
    shares         [T, E, n]  p^a, the credit shares
    agent_rewards  [T, E, n]  r_i^a = p^a R_i, the credited per-agent bonus a trainer adds
    influences     [T, E, n, n] EDTI's c_{i->j} (reward "edti"), else None
"""


class RewardClient(_Client):
    """The credited bonus of a running reward server (docs/credit.md).

    Thread-safe (gRPC channels are); one client per trainer is the intent.
    Each score() carries this client's incarnation and a sequence number, so
    a retry after a lost answer is answered without being counted twice.
    """

    RETRYABLE = ("UNAVAILABLE", "RESOURCE_EXHAUSTED", "DEADLINE_EXCEEDED")

    def __init__(self, address, tls=None, token=None, token_file=None, timeout=30.0, actor_id="python",
                 retries=3):
        super().__init__(address, tls, token, token_file, timeout)
        if not isinstance(actor_id, str) or len(actor_id.encode()) > 256:
            raise ValueError("actor_id: expected a string of at most 256 bytes")
        self.actor_id = actor_id
        self.retries = _env.check_int("retries", retries, 0, 100)
        _, _, self._pb, grpc_mod = _v1()
        self._stub = grpc_mod.RewardServiceStub(self._channel)
        self._incarnation = random.SystemRandom().randrange(1, 2**64)
        self._sequence = 0
        self._served = None

    def stats(self):
        """The server's configuration and counters (RewardStats) as a dict."""
        return _message_dict(self._call("GetStats", self._stub.GetStats, self._pb.GetStatsRequest()))

    def score(self, states, actions, probs, next_states=None, episode_ids=None, terminated=None, env=None,
              dry_run=False, policy_version=None):
        """Scores T steps of E environments and returns a ScoreResult.

        states      [T+1, E, K] int  compact states: states[t] is where actions[t] were taken
        actions     [T, E, n] int    in [0, A)
        probs       [T, E, n, A] float32  the policy's probabilities (rows sum to 1)
        next_states [T, E, K] int    the state each step reached (info["final_state"]);
                                     default states[1:] (right unless an episode ended)
        episode_ids [T, E] int       (info["episode_id"]) SF and EDTI keep per-episode
                                     state by it; default 0
        terminated  [T, E] bool      SF stops its successor sums there; default none
        env         an imca env: its scenario fingerprint is sent (the server then refuses
                    another map or rules); default: the server's scenario is taken on trust
        dry_run     score without updating the server's counts or models
        policy_version  the version of the policy that acted: a reward server started with
                    --deterministic scores every call of a version against the state the
                    version's first call found (docs/credit.md); default: this call's
                    sequence number, so that each call is a version of its own
        Raises ValueError naming the argument for bad shapes or values (nothing
        is sent), ServiceError for a refusal.
        """
        served = self._served_scenario()
        probs = np.asarray(probs)
        if probs.dtype != np.float32:
            raise TypeError(f"probs: expected a float32 array, got dtype {probs.dtype}")
        if probs.ndim != 4:
            raise ValueError(f"probs: expected shape (T, E, n, A), got {probs.shape}")
        T, E, n, A = probs.shape
        if n != served["num_agents"]:
            raise ValueError(f"probs: {n} agents, the server serves {served['num_agents']} ({served['scenario']})")
        states = _ints("states", states, (T + 1, E, None))
        K = states.shape[2]
        actions = _ints("actions", actions, (T, E, n))
        if actions.size and (actions.min() < 0 or actions.max() >= A):
            bad = np.argwhere((actions < 0) | (actions >= A))[0]
            raise ValueError(f"actions[{', '.join(map(str, bad))}] = {actions[tuple(bad)]} is not in [0, {A})")
        if not np.all(np.isfinite(probs)) or probs.min(initial=0) < 0:
            raise ValueError("probs: not probabilities (negative or non-finite values)")
        sums = probs.sum(axis=-1, dtype=np.float64)
        if np.any(np.abs(sums - 1) > 1e-3):
            bad = np.argwhere(np.abs(sums - 1) > 1e-3)[0]
            raise ValueError(f"probs[{', '.join(map(str, bad))}] sums to {sums[tuple(bad)]:.6f}, not 1")
        next_states = states[1:] if next_states is None else _ints("next_states", next_states, (T, E, K))
        episode_ids = (np.zeros((T, E), np.int64) if episode_ids is None
                       else _ints("episode_ids", episode_ids, (T, E)))
        if terminated is not None:
            terminated = np.asarray(terminated)
            if terminated.dtype != np.bool_ or terminated.shape != (T, E):
                raise ValueError(f"terminated: expected a bool array of shape ({T}, {E}), "
                                 f"got {terminated.dtype} {terminated.shape}")
        if policy_version is not None and (isinstance(policy_version, bool) or
                                           not isinstance(policy_version, (int, np.integer)) or policy_version < 0):
            raise ValueError(f"policy_version: expected an integer >= 0, got {policy_version!r}")
        if T * E > 65536:
            raise ValueError(f"states: T * E = {T * E} transitions exceed the server's 65536 per call")
        request = self._pb.ScoreRequest(dry_run=bool(dry_run))
        u = request.unroll
        u.scenario = served["scenario"]
        u.actor_id = self.actor_id
        u.length, u.num_envs, u.num_agents, u.num_actions, u.state_size = T, E, n, A, K
        if env is not None:
            u.scenario_fingerprint = env.fingerprint
        self._sequence += 1
        u.incarnation = self._incarnation
        u.sequence = self._sequence
        u.policy_version = self._sequence if policy_version is None else int(policy_version)
        u.states.extend(states.ravel().tolist())
        u.actions.extend(actions.ravel().tolist())
        u.action_probs.extend(probs.ravel().tolist())
        u.next_states.extend(next_states.ravel().tolist())
        u.episode_ids.extend(episode_ids.ravel().tolist())
        if terminated is not None:
            u.terminated.extend(terminated.ravel().tolist())
        response = self._retrying("Score", self._stub.Score, request)
        def arr(field, shape):
            return np.asarray(field, dtype=np.float32).reshape(shape)
        return ScoreResult(arr(response.global_rewards, (T, E)), arr(response.contributions, (T, E, n)),
                           arr(response.shares, (T, E, n)), arr(response.agent_rewards, (T, E, n)),
                           arr(response.influences, (T, E, n, n)) if len(response.influences) else None)

    def snapshot(self):
        """Asks the server to write its state now; returns {path, bytes}."""
        return _message_dict(self._call("Snapshot", self._stub.Snapshot, self._pb.SnapshotRequest()))

    def _served_scenario(self):
        if self._served is None:
            stats = self.stats()
            self._served = {"scenario": stats["scenario"], "num_agents": stats["num_agents"]}
        return self._served

    def _retrying(self, method, rpc, request):
        delay = 0.05
        for attempt in range(self.retries + 1):
            try:
                return self._call(method, rpc, request)
            except ServiceError as error:
                if error.code not in self.RETRYABLE or attempt == self.retries:
                    raise
            time.sleep(delay * (1 + random.random()))
            delay = min(delay * 2, 2.0)


class LearnerClient(_Client):
    """A learner's policies and status (docs/learner.md). Thread-safe."""

    def __init__(self, address, tls=None, token=None, token_file=None, timeout=30.0):
        super().__init__(address, tls, token, token_file, timeout)
        self._pb, grpc_mod, _, _ = _v1()
        self._stub = grpc_mod.LearnerServiceStub(self._channel)

    def get_policy(self, min_version=0, wait_ms=0):
        """The newest imca.Policy if its version >= min_version, else None (not
        modified); with wait_ms > 0 (<= 60000) waits that long for one."""
        from .policy import Policy
        min_version = _env.check_int("min_version", min_version, 0)
        wait_ms = _env.check_int("wait_ms", wait_ms, 0, 60000)
        request = self._pb.GetPolicyRequest(min_version=min_version, wait_ms=wait_ms)
        proto = self._call("GetPolicy", self._stub.GetPolicy, request, timeout=self.timeout + wait_ms / 1000)
        return Policy(proto) if len(proto.tensors) else None

    def status(self):
        """Training progress (LearnerStatus) as a dict."""
        return _message_dict(self._call("GetStatus", self._stub.GetStatus, self._pb.GetStatusRequest()))


def _message_dict(message):
    """{field: value} with every field (defaults included), repeated as lists."""
    out = {}
    for field in message.DESCRIPTOR.fields:
        value = getattr(message, field.name)
        out[field.name] = list(value) if field.label == field.LABEL_REPEATED else value
    return out


def _ints(name, value, shape):
    """`value` as an integer array of `shape` (None: any extent), or an error naming `name`."""
    a = np.asarray(value)
    if a.dtype.kind not in "iu":
        raise TypeError(f"{name}: expected an integer array, got dtype {a.dtype}")
    if a.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, a.shape)):
        want = ", ".join("*" if s is None else str(s) for s in shape)
        raise ValueError(f"{name}: expected shape ({want}), got {a.shape}")
    return a
