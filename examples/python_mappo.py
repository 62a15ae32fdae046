#!/usr/bin/python3
"""A compact MAPPO in PyTorch over imca.make, with its intrinsic rewards from
a running reward server (imca.RewardClient): IMCA's credited bonus in your
own trainer.

    PYTHONPATH=python build/bin/reward_server --scenario coop_nav --reward count &
    PYTHONPATH=python examples/python_mappo.py --reward_server 127.0.0.1:50051

Without --reward_server it starts build/bin/reward_server (count novelty,
IMCA credit) on a free port itself. The PPO settings are ./imca train's for
coop_nav (learner/learner_config.h, common/env/scenarios/coop_nav.cc's tuning): 64 envs x 32
steps = 2048 joint steps per iteration, 4 epochs of 4 minibatches, lr 1e-3
with separate actor and critic Adam optimisers, clip 0.2, entropy 0.01,
gamma 0.99 (both heads), GAE lambda 0.95, 64-wide tanh MLPs, a shared
actor on each agent's observation and a critic on the global state plus the
agent id with an extrinsic and an intrinsic head, value targets normalised
by running moments per head and advantages over the whole batch
(docs/learner.md). It prints one line per
iteration and stops at --target success over the last 200 episodes.
--save writes the actor as a policy.pb that imca.load_policy and imca_env
rollout play.
"""
import argparse
import collections
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "python"))

import numpy as np  # noqa: E402
import torch  # noqa: E402
from torch import nn  # noqa: E402

import imca  # noqa: E402


def mlp(inputs, outputs, hidden, gain_last):
    layers = [nn.Linear(inputs, hidden), nn.Tanh(), nn.Linear(hidden, hidden), nn.Tanh(),
              nn.Linear(hidden, outputs)]
    for layer in layers:
        if isinstance(layer, nn.Linear):
            nn.init.orthogonal_(layer.weight, gain=gain_last if layer is layers[-1] else 2 ** 0.5)
            nn.init.zeros_(layer.bias)
    return nn.Sequential(*layers)


def gae(rewards, values, last_values, terminated, truncated, bootstrap, gamma, lam):
    """Advantages [T, E, n]: episodes end at terminated (no bootstrap) and at
    truncated (bootstrapped from the final state's value)."""
    T = rewards.shape[0]
    adv = torch.zeros_like(rewards)
    running = torch.zeros_like(rewards[0])
    for t in reversed(range(T)):
        next_values = last_values if t == T - 1 else values[t + 1]
        ended = (terminated[t] | truncated[t])[..., None]
        next_values = torch.where(ended, bootstrap[t], next_values)
        next_values = torch.where(terminated[t][..., None], torch.zeros_like(next_values), next_values)
        delta = rewards[t] + gamma * next_values - values[t]
        running = delta + gamma * lam * torch.where(ended, torch.zeros_like(running), running)
        adv[t] = running
    return adv


class RunningMoments:
    """Running mean and population variance per value head, merged batch by
    batch (Chan et al.), from a pseudo-sample of count 1e-4 (common/nn/running_moments.h)."""

    def __init__(self, heads):
        self.mean = torch.zeros(heads, dtype=torch.float64)
        self.var = torch.ones(heads, dtype=torch.float64)
        self.count = 1e-4

    def update(self, x):  # [..., heads]
        x = x.reshape(-1, x.shape[-1]).double()
        n, mean, var = x.shape[0], x.mean(0), x.var(0, unbiased=False)
        total, delta = self.count + n, mean - self.mean
        self.mean = self.mean + delta * n / total
        self.var = (self.var * self.count + var * n + delta ** 2 * self.count * n / total) / total
        self.count = total

    def std(self):
        return self.var.clamp_min(1e-4).sqrt()

    def normalise(self, x):
        return ((x.double() - self.mean) / self.std()).float()

    def denormalise(self, x):
        return (x.double() * self.std() + self.mean).float()


def save_policy(actor, obs_dim, num_actions, version, path):
    """The actor in the learner's export layout (MLP_TANH, policy.<i>.*)."""
    from imca.v1 import learner_service_pb2 as pb
    proto = pb.Policy(version=version, architecture=pb.Policy.MLP_TANH, obs_dim=obs_dim, num_actions=num_actions)
    linear = [m for m in actor if isinstance(m, nn.Linear)]
    for i, layer in enumerate(linear):
        for part, tensor in (("weight", layer.weight), ("bias", layer.bias)):
            t = tensor.detach().cpu().numpy().astype(np.float32)
            proto.tensors.add(name=f"policy.{i}.{part}", shape=list(t.shape), data=t.ravel().tolist())
    with open(path, "wb") as f:
        f.write(proto.SerializeToString())


def start_reward_server(scenario):
    port_file = tempfile.mktemp(prefix="imca-reward-port-")
    server = subprocess.Popen([os.path.join(ROOT, "build", "bin", "reward_server"), f"--scenario={scenario}",
                               "--reward=count", "--listen=127.0.0.1:0", f"--port_file={port_file}"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 30
    while not (os.path.exists(port_file) and open(port_file).read().strip()):
        if server.poll() is not None or time.time() > deadline:
            sys.exit("python_mappo: build/bin/reward_server did not start (run ./imca build)")
        time.sleep(0.05)
    address = f"127.0.0.1:{open(port_file).read().strip()}"
    os.unlink(port_file)
    return server, address


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", default="coop_nav")
    p.add_argument("--reward_server", help="host:port of a running reward server (default: start one)")
    p.add_argument("--envs", type=int, default=64)
    p.add_argument("--unroll", type=int, default=32)
    p.add_argument("--steps", type=int, default=2_000_000, help="budget in joint env steps")
    p.add_argument("--iterations", type=int, default=0, help="stop after this many iterations (0: budget)")
    p.add_argument("--target", type=float, default=0.9, help="stop at this success rate (last 200 episodes)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--threads", type=int, default=1, help="torch threads")
    p.add_argument("--save", help="write the actor here as a policy.pb at the end")
    args = p.parse_args()
    for flag in ("envs", "unroll", "steps"):
        if getattr(args, flag) < 1:
            p.error(f"--{flag}: must be >= 1")

    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    server = None
    if args.reward_server is None:
        server, args.reward_server = start_reward_server(args.scenario)
    bonus = imca.RewardClient(args.reward_server, actor_id=f"python_mappo-{os.getpid()}")
    env = imca.make(args.scenario, num_envs=args.envs, seed=args.seed)
    E, n, A, D, G = env.num_envs, env.num_agents, env.num_actions, env.obs_dim, env.global_dim
    T = args.unroll
    actor = mlp(D, A, 64, 0.01)
    critic = mlp(G + n, 2, 64, 1.0)  # Heads: extrinsic, intrinsic.
    actor_opt = torch.optim.Adam(actor.parameters(), lr=args.lr, eps=1e-5)
    critic_opt = torch.optim.Adam(critic.parameters(), lr=args.lr, eps=1e-5)
    agent_ids = torch.eye(n).expand(E, n, n)

    value_norm = RunningMoments(2)

    def values_of(global_states):  # [..., E, G] -> [..., E, n, 2], denormalised
        g = torch.as_tensor(global_states)
        ids = agent_ids.expand(*g.shape[:-1], n, n)
        return value_norm.denormalise(critic(torch.cat([g[..., None, :].expand(*g.shape[:-1], n, G), ids], -1)))

    obs, info = env.reset(seed=args.seed)
    rng = np.random.default_rng(args.seed)
    successes = collections.deque(maxlen=200)
    steps, iteration, start = 0, 0, time.time()
    reached = None
    while steps < args.steps and (args.iterations == 0 or iteration < args.iterations):
        iteration += 1
        buf = collections.defaultdict(list)
        states = [info["state"]]
        with torch.no_grad():
            for t in range(T):
                probs = torch.softmax(actor(torch.as_tensor(obs)), -1).numpy()
                u = (np.cumsum(probs, -1) <= rng.random((E, n, 1))).sum(-1).clip(0, A - 1)
                buf["obs"].append(obs)
                buf["global"].append(info["global_state"])
                buf["actions"].append(u)
                buf["probs"].append(probs.astype(np.float32))
                obs, rewards, terminated, truncated, info = env.step(u)
                buf["rewards"].append(rewards)
                buf["terminated"].append(terminated)
                buf["truncated"].append(truncated)
                buf["final_state"].append(info["final_state"])
                buf["episode_id"].append(info["episode_id"])
                states.append(info["state"])
                for e in np.flatnonzero(terminated | truncated):
                    successes.append(bool(info["success"][e]))
        steps += T * E
        stack = {k: np.stack(v) for k, v in buf.items()}
        # The credited bonus r_i^a of every transition, from the reward server.
        scored = bonus.score(np.stack(states), stack["actions"], stack["probs"], next_states=stack["final_state"],
                             episode_ids=stack["episode_id"], terminated=stack["terminated"], env=env)
        with torch.no_grad():
            values = values_of(stack["global"])                    # [T, E, n, 2]
            last_values = values_of(info["global_state"])          # [E, n, 2]
            bootstrap = values_of(env.global_state(stack["final_state"]))
            term = torch.as_tensor(stack["terminated"])
            trunc = torch.as_tensor(stack["truncated"])
            adv_ext = gae(torch.as_tensor(stack["rewards"]), values[..., 0], last_values[..., 0], term, trunc,
                          bootstrap[..., 0], 0.99, 0.95)
            adv_int = gae(torch.as_tensor(scored.agent_rewards), values[..., 1], last_values[..., 1], term, trunc,
                          bootstrap[..., 1], 0.99, 0.95)
            returns = torch.stack([adv_ext + values[..., 0], adv_int + values[..., 1]], -1)
            value_norm.update(returns)
            adv = adv_ext + adv_int
            adv = ((adv.double() - adv.double().mean()) / (adv.double().std(unbiased=False) + 1e-8)).float()
            old_logp = torch.log(torch.as_tensor(stack["probs"]).gather(
                -1, torch.as_tensor(stack["actions"])[..., None]).squeeze(-1).clamp_min(1e-12))
        flat = {"obs": torch.as_tensor(stack["obs"]).reshape(-1, D),
                "critic_in": torch.cat([torch.as_tensor(stack["global"])[..., None, :].expand(T, E, n, G),
                                        agent_ids.expand(T, E, n, n)], -1).reshape(-1, G + n),
                "actions": torch.as_tensor(stack["actions"]).reshape(-1).long(),
                "old_logp": old_logp.reshape(-1), "adv": adv.reshape(-1),
                "targets": value_norm.normalise(returns).reshape(-1, 2)}
        B = flat["adv"].shape[0]
        for _ in range(4):
            for idx in torch.randperm(B).chunk(4):
                a = flat["adv"][idx]
                dist = torch.distributions.Categorical(logits=actor(flat["obs"][idx]))
                ratio = torch.exp(dist.log_prob(flat["actions"][idx]) - flat["old_logp"][idx])
                policy_loss = -torch.min(ratio * a, ratio.clamp(0.8, 1.2) * a).mean()
                actor_loss = policy_loss - 0.01 * dist.entropy().mean()
                actor_opt.zero_grad()
                actor_loss.backward()
                nn.utils.clip_grad_norm_(actor.parameters(), 0.5)
                actor_opt.step()
                value_loss = 0.5 * (critic(flat["critic_in"][idx]) - flat["targets"][idx]).pow(2).sum(-1).mean()
                critic_opt.zero_grad()
                value_loss.backward()
                nn.utils.clip_grad_norm_(critic.parameters(), 0.5)
                critic_opt.step()
        rate = float(np.mean(successes)) if successes else 0.0
        wall = time.time() - start
        print(f"iteration {iteration} steps {steps} success {rate:.3f} episodes {len(successes)} "
              f"bonus {scored.agent_rewards.mean():.4f} steps/s {steps / wall:.0f} wall {wall:.1f}", flush=True)
        if len(successes) >= 200 and rate >= args.target:
            reached = (steps, wall)
            break
    if reached:
        print(f"reached {args.target:.0%} success at {reached[0]} env steps, {reached[1]:.1f} s", flush=True)
    if args.save:
        save_policy(actor, D, A, iteration, args.save)
        print(f"wrote {args.save}", flush=True)
    bonus.close()
    if server is not None:
        server.terminate()
        server.wait()
    return 0


if __name__ == "__main__":
    sys.exit(main())
