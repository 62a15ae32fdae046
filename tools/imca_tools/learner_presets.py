"""Named learner configurations: ./imca train --learner-preset NAME.

A preset is a set of ./imca train options, applied as if given before the
command line's own (which win over it), and recorded in config.json like any
given option, so a resumed run keeps them whatever the presets become.
Every value is stated, also where it equals today's default, so that a
preset means the same configuration when defaults change.

onpolicy: the reference MAPPO, marlbenchmark/on-policy at de66d7a4 with
`--algorithm_name mappo` on MPE-like tasks, as its argument parser resolves
its flags (its `store_false` flags invert): a shared MLP of two tanh layers
of 64 with a LayerNorm after each and none on the input (use_feature_
normalization off), orthogonal init with tanh's gain 5/3 (output gains 0.01
actor, 1 critic); value normalisation by its ValueNorm (use_valuenorm, updated
per minibatch); value loss MSE, unclipped, coefficient 1; separate actor and
critic Adam, lr 1e-3, eps 1e-5; 4 epochs x 4 minibatches over 32 envs x 64
steps = 2048 env steps, collected by the policy being trained; clip 0.2,
entropy 0.01, max grad norm 0.5; gamma 0.99, GAE lambda 0.95; a time-limit
step is terminal (use_proper_time_limits off); one value head on the summed
reward; the centralised critic sees every agent's observation. With one
actor of 32 envs x 64 steps, the reward server counts each version's one
unroll step by step, as the reference counts its steps (docs/learner.md,
"Against the reference MAPPO").
"""

PRESETS = {
    "onpolicy": {
        "--algo": "mappo",
        "--hidden": "64",
        "--layer-norm": "true",
        "--input-norm": "false",
        "--hidden-gain": "1.6666666666666667",
        "--value-norm": "ema",
        "--value-heads": "1",
        "--value-coef": "1",
        "--value-clip": "0",
        "--huber-delta": "0",
        "--separate-optimizers": "true",
        "--lr": "0.001",
        "--epochs": "4",
        "--minibatches": "4",
        "--clip": "0.2",
        "--entropy-coef": "0.01",
        "--max-grad-norm": "0.5",
        "--objective": "behaviour",
        "--gamma": "0.99",
        "--lambda": "0.95",
        "--intrinsic-coef": "1",
        "--time-limit": "terminal",
        "--critic-input": "joint_obs",
        "--sync": "true",
        "--batch-steps": "2048",
        "--actors": "1",
        "--envs-per-actor": "32",
        "--unroll-length": "64",
    },
}


def names():
    return sorted(PRESETS)


def argv(name):
    """The preset's options as ./imca train arguments. KeyError if unknown."""
    return [f"{flag}={value}" for flag, value in PRESETS[name].items()]
