"""Training on the changing pile: a shift's pile scooped again and again without the carry (RepeatedPileEnv), and
the recipe key that puts it among a run's simulators."""

from __future__ import annotations

import numpy as np
import pytest

from autoscoop.agents.heuristic import HeuristicScooper
from autoscoop.core.config import RandomizeConfig, ScoopConfig
from autoscoop.envs import shift as shift_env
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import ScoopEnv
from autoscoop.envs.shift import RepeatedPileEnv, make_repeated_pile_env
from autoscoop.training.factories import make_vec_env, repeated_pile_envs

SMALL_PILE = {"shift.pile_particles": 144, "shift.pile_layers": 3, "pile.variants": 1}


@pytest.fixture(scope="module")
def two_scoops():
    """Two heuristic scoops on one small repeated pile: the environment and what was read after each."""
    env = make_repeated_pile_env(ScoopConfig().with_overrides(SMALL_PILE))
    scoop_env = env.unwrapped
    policy = HeuristicScooper()
    seen = []
    for seed in (0, 1):
        outcome = rollout(policy, env, seed)
        sim = scoop_env.sim
        seen.append({"outcome": outcome, "scoops_on_pile": scoop_env.scoops_on_pile,
                     "delivered": int(sim.delivered.sum()), "in_bucket": int(sim.particles_in_bucket().sum())})
    env.reset(seed=2)  # the third scoop's start
    return env, seen


def test_the_next_scoop_starts_on_the_pile_the_last_one_left(two_scoops):
    env, seen = two_scoops
    scoop_env, sim = env.unwrapped, env.unwrapped.sim
    assert [s["scoops_on_pile"] for s in seen] == [1, 2] and scoop_env.scoops_on_pile == 3
    assert seen[0]["delivered"] == 0 and seen[0]["in_bucket"] > 0, "the first scoop takes from a fresh pile"
    # what each scoop lifted was taken away before the next began; the pile kept everything else
    assert seen[1]["delivered"] >= seen[0]["in_bucket"]
    assert int(sim.delivered.sum()) >= seen[1]["delivered"] + seen[1]["in_bucket"]
    assert sim.toe_shift_m > 0.0, "the face retreated"
    assert np.all(np.isfinite(sim.particle_positions))


def test_each_later_scoop_starts_at_rest_start_gap_short_of_the_new_toe(two_scoops):
    env, _ = two_scoops
    sim, cfg = env.unwrapped.sim, env.unwrapped.config
    assert abs(sim.toe_x_m()) < 1e-9, "the world is moved so that the toe is at x = 0"
    gap = -float(sim.tip_world[0])
    assert abs(gap - cfg.robot.start_gap_m) <= cfg.robot.start_gap_jitter_m + 0.01
    assert abs(sim.lift_rad - cfg.robot.start_lift_rad) < 0.02 and abs(sim.tilt_rad - cfg.robot.start_tilt_rad) < 0.02
    assert abs(sim.odometry_speed_mps) < 1e-6
    assert sim.elapsed_s == 0.0
    assert not sim.particles_in_bucket().any(), "the bucket starts empty"
    off_pile = ~sim.delivered & ~sim.pile_mask()
    assert not (off_pile & (sim.particle_positions[:, 0] < 0.0)).any(), "nothing lies where the loader stands"


def test_a_fresh_pile_follows_the_last_scoop_of_a_pile(monkeypatch):
    monkeypatch.setattr(shift_env, "SCOOPS_PER_TRAINING_PILE", 2)
    env = make_repeated_pile_env(ScoopConfig().with_overrides(SMALL_PILE))
    scoop_env = env.unwrapped
    policy = HeuristicScooper()
    counts = []
    for seed in range(3):
        rollout(policy, env, seed)
        counts.append(scoop_env.scoops_on_pile)
    assert counts == [1, 2, 1]
    assert not scoop_env.sim.delivered.any() and scoop_env.sim.toe_shift_m == 0.0, "a fresh pile, nothing delivered"


def test_it_stays_in_its_one_world_whatever_the_curriculum_says():
    env = RepeatedPileEnv(ScoopConfig().with_overrides({**SMALL_PILE, "randomize.preset": "robot"}))
    assert not env.config.randomize.active, "built in the config's one world"
    env.set_randomize(RandomizeConfig(preset="robot"))
    assert not env.config.randomize.active
    assert env.sim.n_particles == SMALL_PILE["shift.pile_particles"]


def test_the_recipe_key_names_how_many_simulators_scoop_the_repeated_pile():
    assert repeated_pile_envs({}, 2) == 0 and repeated_pile_envs({"repeated_pile_envs": 1}, 2) == 1
    for bad in (-1, 3, 1.5, True, "1"):
        with pytest.raises(ValueError, match=r"repeated_pile_envs .* allowed whole numbers in \[0, 2\]"):
            repeated_pile_envs({"repeated_pile_envs": bad}, 2)
    vec = make_vec_env(ScoopConfig().with_overrides(SMALL_PILE), 1, seed=0, repeated_pile=1)
    try:
        assert isinstance(vec.envs[0].unwrapped, RepeatedPileEnv)
    finally:
        vec.close()
    vec = make_vec_env(ScoopConfig(), 1, seed=0)
    try:
        assert type(vec.envs[0].unwrapped) is ScoopEnv
    finally:
        vec.close()

