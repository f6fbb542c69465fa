"""The Gymnasium environment: API, determinism, reward terms, bad actions, physics errors."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import autoscoop  # noqa: F401
from autoscoop.core.state import STATE_NAMES
from autoscoop.envs import registered_worlds
from autoscoop.envs.outcome import EpisodeOutcome
from autoscoop.envs.scoop import ScoopEnv
from autoscoop.sim.scene import WHEEL_RADIUS_M, WHEELS

SMALL = {"pile.variants": 2}


def rollout(env, seed, actions):
    obs, _ = env.reset(seed=seed)
    trace = [obs]
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        trace.append(np.append(obs, reward))
        if terminated or truncated:
            break
    return trace


@pytest.mark.parametrize("env_id", sorted(registered_worlds()))
def test_check_env_passes_for_every_registered_id(env_id):
    check_env(gym.make(env_id, **SMALL).unwrapped, skip_render_check=True)


def test_the_registered_ids_are_the_paper_world_its_old_odometry_and_the_shipped_policys_world():
    from autoscoop.core.config import ScoopConfig
    from autoscoop.training.settings import config_at, load_recipe

    worlds = registered_worlds()
    assert set(worlds) == {"autoscoop/Scoop-v0", "autoscoop/Scoop-v1", "autoscoop/ScoopRobot-v1"}
    assert gym.make("autoscoop/Scoop-v1").unwrapped.config == ScoopConfig()
    assert gym.make("autoscoop/Scoop-v0").unwrapped.config == ScoopConfig().with_overrides(
        {"sensor.odometry_window_steps": 1})
    # the robot world is where a run of the shipped policy's recipe trains at its end
    spec = load_recipe("ddpg", "robot_smooth")
    trained_in = config_at(ScoopConfig().with_overrides(spec["env"]), spec, spec["episodes"])
    robot = gym.make("autoscoop/ScoopRobot-v1").unwrapped.config
    assert robot == trained_in
    assert robot.randomize.preset == "robot" and robot.sensor.level_with_imu
    # keys given to gym.make are laid over the id's own
    assert gym.make("autoscoop/ScoopRobot-v1", **{"pile.angle_deg": 25}).unwrapped.config == \
        trained_in.with_overrides({"pile.angle_deg": 25})
    # every id has its entry in the class docstring's version history
    history = ScoopEnv.__doc__.split("## Version History")[1]
    assert all(f"``{env_id}``" in history for env_id in worlds)


def test_scoop_v0_reads_the_instantaneous_wheel_speed_and_v1_the_mean_of_two_physics_steps():
    def speeds(env_id):
        env = gym.make(env_id, **SMALL)
        env.reset(seed=3)
        data, out = env.unwrapped.sim.data, []
        for _ in range(6):
            obs, *_ = env.step(np.array([1.0, 0.3, 0.0], dtype=np.float32))
            now = np.mean([data.joint(wheel).qvel[0] for wheel in WHEELS]) * WHEEL_RADIUS_M
            out.append((obs[STATE_NAMES.index("v")], np.float32(now)))
        return out

    assert all(read == now for read, now in speeds("autoscoop/Scoop-v0"))
    assert any(read != now for read, now in speeds("autoscoop/Scoop-v1"))


def test_spaces_match_the_paper():
    env = ScoopEnv(**SMALL)
    assert env.action_space.shape == (3,) and env.observation_space.shape == (12,)
    assert len(STATE_NAMES) == 12 and STATE_NAMES[0] == "w" and STATE_NAMES[5] == "d_pile"


def test_same_seed_gives_the_same_episode():
    actions = np.random.default_rng(0).uniform(-1, 1, size=(12, 3))
    first = rollout(ScoopEnv(**SMALL), 7, actions)
    second = rollout(ScoopEnv(**SMALL), 7, actions)
    assert len(first) == len(second)
    for a, b in zip(first, second):
        np.testing.assert_array_equal(a, b)


def test_reward_terms_sum_to_the_reward_and_info_is_complete():
    env = ScoopEnv(**SMALL)
    env.reset(seed=1)
    keys = {"particles_in_bucket", "mass_in_bucket_kg", "fill_factor", "penetrating", "success", "spilled",
            "physics_error", "reward_progress", "reward_mass"}
    for action in np.random.default_rng(1).uniform(-1, 1, size=(10, 3)):
        _, reward, terminated, _, info = env.step(action)
        assert keys <= set(info)
        assert info["reward_progress"] + info["reward_mass"] == pytest.approx(reward)
        assert 0.0 <= info["reward_progress"] <= 1.0
        if terminated:
            break


def test_nan_action_is_refused_and_out_of_range_is_clipped():
    env = ScoopEnv(**SMALL)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="non-finite.*lift"):
        env.step(np.array([0.0, np.nan, 0.0]))
    with pytest.raises(ValueError, match="3 numbers"):
        env.step(np.zeros(4))
    env.step(np.array([50.0, 0.0, 0.0]))
    wheel_speeds = env.sim.data.ctrl[[env.sim.model.actuator(w).id for w in WHEELS]] * WHEEL_RADIUS_M
    assert wheel_speeds == pytest.approx([env.config.robot.max_speed_mps] * len(WHEELS))  # the speed target


def test_instability_ends_the_episode_with_a_physics_error():
    env = ScoopEnv(**SMALL)
    env.reset(seed=0)
    env.sim.data.qvel[:] = 1e12  # a diverging simulation
    obs, reward, terminated, truncated, info = env.step(np.zeros(3))
    assert terminated and not truncated and info["physics_error"]
    assert np.all(np.isfinite(obs)) and reward == 0.0


def test_reaching_pays_the_mass_bonus_and_reports_cycle_time():
    at_start = {"reward.terminal_dx_m": -0.1, "reward.terminal_z_m": 0.03, "reward.epsilon_m": 0.1}
    env = ScoopEnv(**SMALL, **at_start, **{"scoop.min_fill": 0.0})
    env.reset(seed=0)
    _, reward, terminated, _, info = env.step(np.zeros(3))
    assert terminated and info["reached"] and info["success"] and info["cycle_time_s"] == pytest.approx(0.25)
    assert info["reward_mass"] == pytest.approx(env.config.reward.c_w * info["fill_factor"])


def test_an_empty_lift_reaches_but_is_no_success():
    """Success is a scoop: the terminal point reached with at least scoop.min_fill of mass or volume."""
    env = ScoopEnv(**SMALL, **{"reward.terminal_dx_m": -0.1, "reward.terminal_z_m": 0.03, "reward.epsilon_m": 0.1})
    env.reset(seed=0)
    _, _, terminated, _, info = env.step(np.zeros(3))
    assert terminated and info["reached"] and info["fill_factor"] == 0.0 and info["volumetric_fill"] == 0.0
    assert not info["success"]
    outcome = EpisodeOutcome.from_info(info, seed=0, steps=1, episode_return=0.0)
    assert outcome.reached and not outcome.success and outcome.cycle_time_s is None


def test_terminal_distance_is_measured_in_the_arms_plane():
    """A loader that drifted sideways (unobservable in the state) is as far from the terminal point."""
    env = ScoopEnv(**SMALL)
    env.reset(seed=0)
    _, _, _, _, straight = env.step(np.zeros(3))
    env.reset(seed=0)
    root = env.sim.model.joint("root").qposadr[0]
    env.sim.data.qpos[root + 1] += 0.08  # 8 cm to the side
    _, _, _, _, drifted = env.step(np.zeros(3))
    tip = env.sim.tip_world
    assert abs(tip[1]) > 0.07
    expected = np.hypot(tip[0] - env.config.reward.terminal_dx_m, tip[2] - env.config.reward.terminal_z_m)
    assert drifted["tip_to_terminal_m"] == pytest.approx(expected)
    assert drifted["tip_to_terminal_m"] == pytest.approx(straight["tip_to_terminal_m"], abs=2e-3)


@pytest.mark.parametrize("command", ["train", "eval", "stress"])
def test_train_eval_and_stress_say_how_their_config_names_the_registered_ids(command, capsys):
    from autoscoop.cli import main

    with pytest.raises(SystemExit):
        main([command, "--help"])
    text = "".join(capsys.readouterr().out.split())  # argparse wraps lines, at hyphens too
    for env_id, keys in registered_worlds().items():
        assert env_id in text and all(f"{key}=" in text for key in keys)


def test_energy_cost_charges_the_work_of_each_period_and_more_for_a_busier_one():
    """reward.c_energy: each step's term is the actuators' positive work over that period, measured in the scene
    the episode runs in; driving and lifting cost more than holding still, and the other terms are unchanged."""
    costed, plain = ScoopEnv(**SMALL, **{"reward.c_energy": 1.0}), ScoopEnv(**SMALL)
    work = {}
    for name, action in (("still", np.zeros(3)), ("busy", np.array([1.0, -1.0, -1.0]))):
        for env in (costed, plain):
            env.reset(seed=3)
        _, reward, _, _, info = costed.step(action)
        _, plain_reward, _, _, plain_info = plain.step(action)
        work[name] = -info["reward_energy"]
        assert "reward_energy" not in plain_info
        assert reward == pytest.approx(plain_reward - work[name])
    assert work["busy"] > 1.0 > work["still"] >= 0.0
