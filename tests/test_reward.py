"""The reward's bonus: the paper's mass bonus, and the two options for a world whose material varies."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autoscoop.core.config import ConfigError, RewardConfig, ScoopConfig
from autoscoop.core.reward import action_change, scoop_reward

AT_GOAL = dict(tip_to_pile_m=0.3, tip_to_terminal_m=0.0, penetrating=True)


def bonus(w: float, volumetric: float = 0.0, **settings) -> float:
    _, terms = scoop_reward(**AT_GOAL, w=w, config=RewardConfig(c_w=50.0, **settings), volumetric_fill=volumetric)
    return terms["reward_mass"]


def test_paper_bonus_pays_mass_up_to_the_rated_load_and_ignores_volume():
    assert bonus(0.6, volumetric=0.9) == pytest.approx(30.0)
    assert bonus(1.4) == pytest.approx(50.0)


def test_scoop_measure_pays_the_higher_of_mass_and_volume_up_to_one():
    assert bonus(0.45, volumetric=0.8, fill_measure="scoop") == pytest.approx(40.0)  # light earth: by volume
    assert bonus(0.9, volumetric=0.6, fill_measure="scoop") == pytest.approx(45.0)  # heavy earth: by mass
    assert bonus(0.9, volumetric=1.2, fill_measure="scoop") == pytest.approx(50.0)


def test_overload_cost_takes_off_the_mass_above_the_rated_load():
    assert bonus(1.0, c_overload=100.0) == pytest.approx(50.0)
    assert bonus(1.2, c_overload=100.0) == pytest.approx(30.0)
    assert bonus(0.8, c_overload=100.0) == pytest.approx(40.0)


def test_overload_margin_makes_the_bonus_peak_short_of_the_rated_load():
    # reward.overload_from 0.9: heavy earth's bonus is highest at w = 0.9, and falls c_overload per unit above
    assert bonus(0.9, c_overload=100.0, overload_from=0.9) == pytest.approx(45.0)
    assert bonus(1.0, c_overload=100.0, overload_from=0.9) == pytest.approx(40.0)
    assert bonus(0.8, c_overload=100.0, overload_from=0.9) == pytest.approx(40.0)
    peak = max((bonus(w / 100, c_overload=100.0, overload_from=0.9), w / 100) for w in range(50, 130))
    assert peak[1] == pytest.approx(0.9)


def test_no_bonus_away_from_the_terminal_point():
    _, terms = scoop_reward(0.3, 0.5, True, 1.0, RewardConfig(fill_measure="scoop", c_overload=10.0), 1.0)
    assert terms["reward_mass"] == 0.0


def test_bad_settings_name_the_key():
    with pytest.raises(ConfigError, match="fill_measure"):
        RewardConfig.from_dict({"fill_measure": "volume"})
    with pytest.raises(ConfigError, match="c_overload"):
        RewardConfig.from_dict({"c_overload": -1.0})
    with pytest.raises(ConfigError, match="overload_from"):
        RewardConfig.from_dict({"overload_from": 0.1})


def test_pitch_cost_charges_each_degree_nose_down_beyond_the_threshold():
    config = RewardConfig(c_pitch=0.5, pitch_from_deg=8.0)
    reward, terms = scoop_reward(0.3, 0.5, False, 0.0, config, chassis_pitch_rad=math.radians(12.0))
    assert terms["reward_pitch"] == pytest.approx(-2.0)  # 4 degrees beyond 8, 0.5 each
    assert reward == pytest.approx(sum(terms.values()))
    _, level = scoop_reward(0.3, 0.5, False, 0.0, config, chassis_pitch_rad=math.radians(7.9))
    _, tail_down = scoop_reward(0.3, 0.5, False, 0.0, config, chassis_pitch_rad=math.radians(-15.0))
    assert level["reward_pitch"] == 0.0 and tail_down["reward_pitch"] == 0.0


def test_pitch_cost_off_by_default_leaves_the_papers_terms():
    reward, terms = scoop_reward(0.3, 0.5, False, 0.0, RewardConfig(), chassis_pitch_rad=math.radians(20.0))
    assert set(terms) == {"reward_progress", "reward_mass"}
    assert reward == terms["reward_progress"]
    with pytest.raises(ConfigError, match="c_pitch"):
        RewardConfig.from_dict({"c_pitch": -1.0})


def test_action_change_is_the_mean_squared_halved_change_clipped_to_the_action_range():
    assert action_change([0.0, 0.0, 0.0], [0.0, 0.0, 0.0]) == 0.0
    assert action_change([1.0, 1.0, 1.0], [-1.0, -1.0, -1.0]) == pytest.approx(1.0)  # a full flip of all three
    assert action_change([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]) == pytest.approx(0.25 / 3)
    assert action_change([0.0, 0.0, 0.0], [5.0, 0.0, 0.0]) == action_change([0.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="components"):
        action_change([0.0, 0.0], [0.0, 0.0, 0.0])


def test_action_change_cost_charges_flips_and_is_off_by_default():
    config = RewardConfig(c_action_change=2.0)
    reward, terms = scoop_reward(0.3, 0.5, False, 0.0, config, command_change=0.5)
    assert terms["reward_action_change"] == pytest.approx(-1.0)
    assert reward == pytest.approx(sum(terms.values()))
    _, paper = scoop_reward(0.3, 0.5, False, 0.0, RewardConfig(), command_change=1.0)
    assert set(paper) == {"reward_progress", "reward_mass"}
    with pytest.raises(ConfigError, match="c_action_change"):
        RewardConfig.from_dict({"c_action_change": -1.0})


def test_the_environment_charges_a_flipping_controller_and_not_a_steady_one():
    from autoscoop.envs.scoop import make_scoop_env

    env = make_scoop_env(ScoopConfig().with_overrides({"pile.variants": 1, "reward.c_action_change": 1.0}))
    env.reset(seed=0)
    costs = [env.step(np.array([sign, -sign, sign]))[4]["reward_action_change"] for sign in (1.0, -1.0, 1.0)]
    assert costs == pytest.approx([-0.25, -1.0, -1.0])  # from still (a_-1 = 0), then full flips
    env.reset(seed=0)  # a new episode starts from still again
    steady = [env.step(np.array([0.5, 0.5, 0.5]))[4]["reward_action_change"] for _ in range(3)]
    assert steady == pytest.approx([-0.0625, 0.0, 0.0])
    env.close()


def test_approach_height_cost_charges_a_raised_tip_until_the_pile_is_reached():
    config = RewardConfig(c_approach_height=10.0, approach_height_from_m=0.06)
    reward, terms = scoop_reward(0.3, 0.5, False, 0.0, config, approach_height_m=0.16)
    assert terms["reward_approach_height"] == pytest.approx(-1.0)
    assert reward == pytest.approx(sum(terms.values()))
    assert scoop_reward(0.3, 0.5, False, 0.0, config, approach_height_m=0.05)[1]["reward_approach_height"] == 0.0
    assert scoop_reward(0.3, 0.5, True, 0.0, config, approach_height_m=None)[1]["reward_approach_height"] == 0.0
    _, paper = scoop_reward(0.3, 0.5, False, 0.0, RewardConfig(), approach_height_m=0.3)
    assert set(paper) == {"reward_progress", "reward_mass"}
    with pytest.raises(ConfigError, match="c_approach_height"):
        RewardConfig.from_dict({"c_approach_height": -1.0})


def test_the_environment_charges_a_raised_approach_and_stops_once_the_tip_reaches_the_pile():
    from autoscoop.envs.scoop import make_scoop_env

    env = make_scoop_env(ScoopConfig().with_overrides({"pile.variants": 1, "reward.c_approach_height": 10.0}))
    env.reset(seed=0)
    raised = [env.step(np.array([0.0, -0.5, 0.0]))[4] for _ in range(3)]  # lift: the tip rises, the loader stands
    assert raised[-1]["reward_approach_height"] < -0.5
    env.reset(seed=0)
    infos = [env.step(np.array([1.0, 0.0, 0.0]))[4] for _ in range(8)]  # drive in low
    touched = next(i for i, info in enumerate(infos) if info["penetrating"])
    assert all(info["reward_approach_height"] == 0.0 for info in infos)
    infos = [env.step(np.array([0.0, -0.5, 0.0]))[4] for _ in range(3)]  # lifting after the pile is free
    assert touched < 8 and all(info["reward_approach_height"] == 0.0 for info in infos)
    env.close()


def test_time_cost_makes_lingering_short_of_the_terminal_point_cost_and_is_off_by_default():
    config = RewardConfig(c_time=1.0)
    reward, terms = scoop_reward(0.3, 0.05, True, 0.0, config)  # hovering: the progress term pays nearly 1
    assert terms["reward_time"] == -1.0
    assert reward == pytest.approx(sum(terms.values())) and reward <= 0.0
    reached, reached_terms = scoop_reward(0.3, 0.05, True, 0.8, config)
    assert reached_terms["reward_mass"] > 0.0 and reached == pytest.approx(sum(reached_terms.values()))
    _, paper = scoop_reward(0.3, 0.05, True, 0.0, RewardConfig())
    assert set(paper) == {"reward_progress", "reward_mass"}
    with pytest.raises(ConfigError, match="c_time"):
        RewardConfig.from_dict({"c_time": -1.0})


def test_overload_step_cost_charges_every_step_above_its_threshold_and_is_off_by_default():
    config = RewardConfig(c_overload_step=10.0)
    overload_fill = ScoopConfig().scoop.overload_fill  # 1.05: what evaluation counts as an overload
    reward, terms = scoop_reward(0.3, 0.5, True, 1.25, config, overload_fill=overload_fill)  # carrying 1.25
    assert terms["reward_overload_step"] == pytest.approx(-2.0)
    assert reward == pytest.approx(sum(terms.values()))
    assert scoop_reward(0.3, 0.5, True, 1.0, config, overload_fill=overload_fill)[1]["reward_overload_step"] == 0.0
    _, paper = scoop_reward(0.3, 0.5, True, 1.25, RewardConfig())
    assert set(paper) == {"reward_progress", "reward_mass"}
    with pytest.raises(ValueError, match="overload_fill"):
        scoop_reward(0.3, 0.5, True, 1.25, config)
    with pytest.raises(ConfigError, match="c_overload_step"):
        RewardConfig.from_dict({"c_overload_step": -1.0})


def test_energy_cost_charges_the_periods_actuator_work_and_is_off_by_default():
    config = RewardConfig(c_energy=0.1)
    reward, terms = scoop_reward(0.3, 0.5, True, 0.5, config, actuator_work_j=12.0)
    assert terms["reward_energy"] == pytest.approx(-1.2)
    assert reward == pytest.approx(sum(terms.values()))
    assert scoop_reward(0.3, 0.5, True, 0.5, config)[1]["reward_energy"] == 0.0  # a still loader spends nothing
    _, paper = scoop_reward(0.3, 0.5, True, 0.5, RewardConfig(), actuator_work_j=12.0)
    assert set(paper) == {"reward_progress", "reward_mass"}
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="actuator_work_j"):
            scoop_reward(0.3, 0.5, True, 0.5, config, actuator_work_j=bad)
    with pytest.raises(ConfigError, match="c_energy"):
        RewardConfig.from_dict({"c_energy": -1.0})


def test_success_bonus_is_paid_on_reaching_loaded_by_mass_or_volume_and_is_off_by_default():
    config = RewardConfig(c_success=20.0)
    _, loaded = scoop_reward(0.3, 0.05, True, 0.5, config, min_fill=0.5)  # at the terminal point, w at the line
    assert loaded["reward_success"] == 20.0
    _, by_volume = scoop_reward(0.3, 0.05, True, 0.3, config, volumetric_fill=0.55, min_fill=0.5)
    assert by_volume["reward_success"] == 20.0
    _, short = scoop_reward(0.3, 0.05, True, 0.49, config, volumetric_fill=0.45, min_fill=0.5)
    assert short["reward_success"] == 0.0
    _, far = scoop_reward(0.3, 0.5, True, 0.9, config, min_fill=0.5)  # loaded, not yet at the terminal point
    assert far["reward_success"] == 0.0
    reward, terms = scoop_reward(0.3, 0.05, True, 0.8, config, min_fill=0.5)
    assert reward == pytest.approx(sum(terms.values()))
    with pytest.raises(ValueError, match="min_fill"):
        scoop_reward(0.3, 0.05, True, 0.8, config)
    _, paper = scoop_reward(0.3, 0.05, True, 0.8, RewardConfig())
    assert "reward_success" not in paper
