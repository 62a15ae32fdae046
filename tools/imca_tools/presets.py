"""The built-in grids of ./imca experiment --preset (docs/experiments.md),
as grid entries (imca_tools.grid), and the results folder edition they
write to.
"""
import functools

from . import binaries


def baselines():
    """The paper's baseline credit modes: every mode but imca."""
    return [c for c in binaries.facts()["credits"] if c != "imca"]


def pairing(scenario, reward, steps, seeds, maddpg=False):
    """The paper's methods on one scenario: three baselines, imca x permutations
    (and with `maddpg` the paper's other learner, MADDPG, without and with the
    IMCA bonus). SF's joint input is not permuted (docs/credit.md: permutations apply
    to count and RND), so its imca runs only with permutation off."""
    entries = [{"scenario": scenario, "reward": reward, "credit": baselines(), "permutation": "off",
                "seed": seeds, "steps": steps},
               {"scenario": scenario, "reward": reward, "credit": "imca",
                "permutation": "off" if reward == "sf" else binaries.facts()["permutations"], "seed": seeds, "steps": steps}]
    if maddpg:
        entries.append(maddpg_rows(scenario, reward, steps, seeds))
    return entries


def maddpg_rows(scenario, reward, steps, seeds):
    """MADDPG (docs/learner.md) with credit none and with the IMCA bonus."""
    return {"scenario": scenario, "reward": reward, "credit": ["none", "imca"], "permutation": "off",
            "seed": seeds, "steps": steps, "flags": {"algo": "maddpg"}}


# The task versions of CMAE's code and EDTI's (docs/scenarios.md).
CMAE_TASKS = ["pass_cmae", "secret_room_cmae", "push_box_cmae"]


EDTI_TASKS = ["pass", "secret_room"]


# The frontier preset's methods, one seed's worth of entries.
FRONTIER_METHODS = [
    {"scenario": CMAE_TASKS + EDTI_TASKS, "reward": "count", "credit": "none", "permutation": "off",
     "steps": 4_500_000, "flags": {"algo": "cmae"}},
    {"scenario": CMAE_TASKS, "reward": "count", "credit": ["none", "shared", "imca"], "permutation": "off",
     "steps": 4_500_000},
    {"scenario": CMAE_TASKS, "reward": "edti", "credit": "independent", "permutation": "off", "steps": 4_500_000},
    {"scenario": EDTI_TASKS, "reward": "count", "credit": ["none", "shared", "imca"], "permutation": "off",
     "steps": 3_000_000},
    {"scenario": EDTI_TASKS, "reward": "edti", "credit": "independent", "permutation": "off", "steps": 3_000_000},
]


# The multi_room3 preset's methods, one seed's worth of entries: 3 agents,
# where joint-state counts rarely repeat and learned novelty may generalise.
MULTI_ROOM3_METHODS = [
    {"scenario": "multi_room3_mace", "reward": "count", "credit": "none", "permutation": "off",
     "steps": 4_500_000},
    {"scenario": "multi_room3_mace", "reward": ["count", "rnd"], "credit": ["shared", "imca"], "permutation": "off",
     "steps": 4_500_000},
]


def seed_by_seed(methods, seeds):
    """Entries for each seed in turn, every method of one seed before the
    next (a grid cut short holds whole seeds of every method), each cell
    --deterministic."""
    return [dict(entry, seed=seed, flags={**entry.get("flags", {}), "deterministic": True})
            for seed in seeds for entry in methods]


@functools.lru_cache(maxsize=None)
def presets():
    """The built-in grids, by name (built when first asked: they use the
    binaries' lists of credit and permutation modes)."""
    return {
        "paper": {
            "description": "the paper's comparison: coop_nav + count, predator_prey + RND, multi_room + SF; "
                           "credit none/independent/shared/imca, imca with permutation off/random/canonical, "
                           "and MADDPG with credit none/imca; 5 seeds",
            "entries": pairing("coop_nav", "count", 2_000_000, [1, 2, 3, 4, 5], maddpg=True)
            + pairing("predator_prey", "rnd", 2_000_000, [1, 2, 3, 4, 5], maddpg=True)
            + pairing("multi_room", "sf", 4_000_000, [1, 2, 3, 4, 5], maddpg=True),
        },
        "edti": {
            "description": "EDTI's exact tasks pass and secret_room: count novelty with credit none/shared/imca "
                           "against EITI and EDTI (docs/baselines.md), and MADDPG with credit none/imca; 5 seeds; "
                           "3M env steps",
            "entries": [{"scenario": ["pass", "secret_room"], "reward": "count", "credit": ["none", "shared", "imca"],
                         "permutation": "off", "seed": [1, 2, 3, 4, 5], "steps": 3_000_000},
                        maddpg_rows(["pass", "secret_room"], "count", 3_000_000, [1, 2, 3, 4, 5]),
                        {"scenario": ["pass", "secret_room"], "reward": ["eiti", "edti"], "credit": "independent",
                         "permutation": "off", "seed": [1, 2, 3, 4, 5], "steps": 3_000_000}],
        },
        "headline": {
            "description": "the headline comparisons, 10 seeds, --deterministic: EDTI's pass and secret_room with "
                           "count novelty and credit none/shared/imca against EITI and EDTI (3M env steps), and "
                           "coop_nav with count novelty, credit shared and imca with permutation "
                           "off/random/canonical (2M)",
            "entries": [dict(entry, seed=list(range(1, 11)), flags={"deterministic": True}) for entry in [
                {"scenario": ["pass", "secret_room"], "reward": "count", "credit": ["none", "shared", "imca"],
                 "permutation": "off", "steps": 3_000_000},
                {"scenario": ["pass", "secret_room"], "reward": ["eiti", "edti"], "credit": "independent",
                 "permutation": "off", "steps": 3_000_000},
                {"scenario": "coop_nav", "reward": "count", "credit": "shared", "permutation": "off",
                 "steps": 2_000_000},
                {"scenario": "coop_nav", "reward": "count", "credit": "imca",
                 "permutation": binaries.facts()["permutations"], "steps": 2_000_000}]],
        },
        "frontier": {
            "description": "past the paper: CMAE (its released code's tabular method, docs/baselines.md) against "
                           "MAPPO with count novelty and credit none/shared/imca and against EDTI, on CMAE's "
                           "pass_cmae, secret_room_cmae and push_box_cmae (4.5M env steps: CMAE's 15,000 "
                           "episodes of 300; the bonuses at a thousandth, the scale of their +1 reward) and on "
                           "EDTI's pass and secret_room (CMAE 4.5M, the others 3M as in the headline preset); "
                           "10 seeds, --deterministic",
            "entries": seed_by_seed(FRONTIER_METHODS, range(1, 11)),
        },
        "multi_room3": {
            "description": "MACE's 3-agent MultiRoom (multi_room3_mace): count and RND novelty, each with credit "
                           "shared and imca, against MAPPO without a bonus; 4.5M env steps; 5 seeds, "
                           "--deterministic",
            "entries": seed_by_seed(MULTI_ROOM3_METHODS, range(1, 6)),
        },
        "quick": {
            "description": "a cut-down paper preset (2 seeds, smaller budgets) that ends in under 30 minutes on 2 cores",
            "entries": pairing("coop_nav", "count", 1_000_000, [1, 2])
            + pairing("predator_prey", "rnd", 400_000, [1, 2])
            + pairing("multi_room", "sf", 800_000, [1, 2]),
        },
    }


# Presets write to results/<preset>-<edition>, a new edition whenever the
# defaults a cell trains with change (docs/experiments.md, "Presets"): v4
# collects with 2 actors of 16 envs, each env's share of an iteration one
# unroll; results/<preset>-v3 and older hold the runs before (docs/results.md).
PRESET_EDITION = "v4"
