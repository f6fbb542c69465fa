"""The randomised world and the sensor link: each range changes the simulation, the delay shifts the
readings by the right number of physics steps, and ``randomize.preset = none`` is the old world to the bit."""

import hashlib
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from autoscoop.agents.heuristic import HeuristicParams, HeuristicScooper
from autoscoop.core.config import ROBOT_PRESET, ConfigError, RandomizeConfig, ScoopConfig
from autoscoop.core.sensing import RawReadings, SensorNoise, add_noise, delay_steps
from autoscoop.envs.scoop import ScoopEnv, make_scoop_env
from autoscoop.sim.world import draw_world, world_config

SMALL = {"pile.variants": 2}
DIGESTS = Path(__file__).parent / "data" / "preset_none_digests.json"


def started(**overrides) -> tuple[ScoopEnv, np.ndarray, dict]:
    env = ScoopEnv(**{**SMALL, **overrides})
    obs, info = env.reset(seed=3)
    return env, obs, info


def particle_geoms(env: ScoopEnv) -> list[int]:
    m = env.sim.model
    return [m.geom(f"particle_{i:03d}").id for i in range(env.sim.n_particles)]


# each range set to a fixed value away from the default, and what must then differ in the simulation
CHECKS = {
    "pile_angle_deg": (40.0, lambda env: env.sim.pile_angle_deg == 40.0
                       and abs(env.sim.particle_positions[:, 0].max() - started()[0].sim.particle_positions[:, 0].max()) > 0.02),
    "particle_mass_kg": (0.2, lambda env: np.allclose(env.sim.particle_masses, 0.2)
                         and np.allclose(env.sim.model.body_mass[env.sim.model.body("particle_000").id], 0.2)),
    "particle_friction": (0.6, lambda env: np.allclose(env.sim.model.geom_friction[particle_geoms(env), 0], 0.6)),
    "particle_radius_m": (0.03, lambda env: np.allclose(env.sim.model.geom_size[particle_geoms(env), 0], 0.03)),
    "n_particles": (64.0, lambda env: env.sim.n_particles == 64 and len(env.sim.particle_positions) == 64),
    "start_gap_m": (0.3, lambda env: env.sim.tip_world[0] == pytest.approx(-0.3, abs=0.012)),
    "ground_friction": (0.6, lambda env: env.sim.model.geom_friction[env.sim.model.geom("wheel_fl").id, 0] == 0.6),
    "bucket_friction": (0.6, lambda env: all(env.sim.model.geom_friction[g, 0] == 0.6 for g in range(env.sim.model.ngeom)
                                             if env.sim.model.geom(g).name.startswith("bucket_"))),
    "torque_limit_scale": (0.8, lambda env: env.sim.model.actuator_forcerange[env.sim.model.actuator("lift").id, 1]
                           == pytest.approx(0.8 * 150.0)),
    "actuator_speed_scale": (1.2, lambda env: env.sim.model.actuator_ctrlrange[env.sim.model.actuator("tilt").id, 1]
                             == pytest.approx(1.2) and env.episode_config.robot.lift_speed_radps == pytest.approx(0.48)),
    "torque_source_probability": (1.0, lambda env: env.episode_config.env.mass_source == "torque"),
    "load_cell_noise_nm": (3.0, lambda env: env.episode_config.env.load_cell_noise_nm == 3.0),
    "sensor_delay_s": (0.05, lambda env: env.episode_config.sensor.delay_s == 0.05),
    "joint_noise_rad": (0.01, lambda env: env.episode_config.sensor.joint_noise_rad == 0.01),
    "speed_noise_mps": (0.01, lambda env: env.episode_config.sensor.speed_noise_mps == 0.01),
    "range_noise_m": (0.01, lambda env: env.episode_config.sensor.range_noise_m == 0.01),
    "torque_noise_nm": (1.0, lambda env: env.episode_config.sensor.torque_noise_nm == 1.0),
    "prescooped_probability": (1.0, lambda env: env.world["prescooped"]
                               and (env.sim.particle_positions[:, 0] < -3.0).sum() == 12),
}


def test_every_range_has_a_check():
    assert set(CHECKS) | {"torque_offset_nm", "prescoop_particles"} == set(ROBOT_PRESET)
    assert set(ROBOT_PRESET) == set(RandomizeConfig.model_fields) - {"preset"}


@pytest.mark.parametrize("name", sorted(CHECKS))
def test_each_randomised_quantity_changes_the_simulation(name):
    value, changed = CHECKS[name]
    extra = {"randomize.prescoop_particles": 12} if name == "prescooped_probability" else {}
    env, _, info = started(**{f"randomize.{name}": value}, **extra)
    drawn = info["world"]
    assert drawn and all(key in drawn for key in ([name] if "probability" not in name else []))
    assert changed(env), f"randomize.{name} = {value} did not change the simulation: {drawn}"
    # and nothing else was drawn
    assert set(drawn) <= {name, "torque_source", "prescooped", "prescoop_particles"}


def test_a_torque_offset_moves_the_weighed_mass():
    """Eq. 8 weighs the difference of the two joints' torques: a tilt offset above the lift's reads heavier."""
    def weighed(**extra) -> tuple[float, dict]:
        env, obs, info = started(**{"randomize.torque_source_probability": 1.0, "env.load_cell_noise_nm": 0.0}, **extra)
        for _ in range(2):
            obs, *_ = env.step(np.array([-1.0, -0.3, 0.0]))
        return float(obs[0]), info["world"]

    plain, _ = weighed()
    for low, high in ((-3.0, -2.9), (2.9, 3.0)):
        w, world = weighed(**{"randomize.torque_offset_nm": [low, high]})
        lift, tilt = world["torque_offset_nm"]
        assert low <= min(lift, tilt) and max(lift, tilt) <= high and lift != tilt
    w_heavy, world = weighed(**{"randomize.torque_offset_nm": [-3.0, 3.0]})
    lift, tilt = world["torque_offset_nm"]
    assert abs(lift - tilt) > 0.5, world  # seed 3 draws two offsets 0.9 N*m apart
    assert np.sign(w_heavy - plain) == np.sign(tilt - lift) and abs(w_heavy - plain) > 0.02, (plain, w_heavy, world)


def test_a_prescooped_face_is_cut_back():
    untouched = started()[0].sim.particle_positions
    env, _, info = started(**{"randomize.prescooped_probability": 1.0, "randomize.prescoop_particles": 12})
    assert info["world"]["prescoop_particles"] == 12
    pile = env.sim.particle_positions[env.sim.particle_positions[:, 0] > -1.0]
    assert len(pile) < len(untouched)
    assert np.sort(pile[:, 0])[:8].mean() > np.sort(untouched[:, 0])[:8].mean() + 0.03  # the toe moved back


def test_draws_are_in_info_and_differ_between_episodes_but_repeat_with_the_seed():
    env = ScoopEnv(**SMALL, **{"randomize.preset": "robot"})
    _, first = env.reset(seed=1)
    _, second = env.reset(seed=2)
    _, again = env.reset(seed=1)
    assert set(first["world"]) >= {"pile_angle_deg", "particle_mass_kg", "start_gap_m", "sensor_delay_s"}
    assert first["world"] != second["world"] and first["world"] == again["world"]
    _, _, _, _, info = env.step(np.zeros(3))
    assert info["world"] == again["world"]


def test_a_range_with_equal_ends_is_a_fixed_value_and_preset_ranges_can_be_replaced():
    config = ScoopConfig().with_overrides({"randomize.preset": "robot", "randomize.pile_angle_deg": 30})
    rng = np.random.default_rng(0)
    assert {draw_world(config, rng)["pile_angle_deg"] for _ in range(5)} == {30.0}
    assert world_config(config, draw_world(config, rng)).pile.angle_deg == 30.0
    with pytest.raises(ConfigError, match="randomize.pile_angle_deg"):
        ScoopConfig().with_overrides({"randomize.pile_angle_deg": "[40, 30]"})
    with pytest.raises(ConfigError, match="randomize.torque_source_probability"):
        ScoopConfig().with_overrides({"randomize.torque_source_probability": 1.5})


def test_delay_shifts_the_readings_by_whole_physics_steps():
    """The delayed state's joint angles are the undelayed simulation's, that many physics steps earlier."""
    for steps in (3, 12, 15):  # within a control period, exactly one, and more than one
        delay = steps * ScoopConfig().env.timestep_s
        assert delay_steps(delay, ScoopConfig().env.timestep_s) == steps
        plain = ScoopEnv(**SMALL)
        delayed = ScoopEnv(**SMALL, **{"sensor.delay_s": round(delay, 6)})
        plain.reset(seed=0)
        delayed.reset(seed=0)
        lift_per_step = [plain.sim.lift_rad]

        def record(sim=plain.sim, out=lift_per_step) -> None:
            out.append(sim.lift_rad)

        plain.sim.add_substep_observer(record)
        substeps = plain.config.substeps
        actions = [np.array([1.0, -0.3, 0.4])] * 6
        for j, action in enumerate(actions, start=1):
            plain.step(action)
            obs, *_ = delayed.step(action)
            expected = lift_per_step[max(0, j * substeps - steps)]
            assert float(obs[7]) == pytest.approx(expected, abs=1e-6), (steps, j)
        assert plain.sim.lift_rad == delayed.sim.lift_rad  # the delay changes what is read, not the physics


def test_delay_is_honoured_to_the_step():
    step = ScoopConfig().env.timestep_s
    assert delay_steps(0.05, step) == 2  # 2.4 steps
    assert delay_steps(0.0, step) == 0
    with pytest.raises(ValueError):
        delay_steps(-0.1, step)


def test_noise_is_shared_drawn_only_where_set_and_averaged_torque_noise_shrinks():
    true = RawReadings(lift_rad=0.1, tilt_rad=0.2, speed_mps=0.05, range_m=0.0, tilt_torque_nm=5.0, lift_torque_nm=40.0)
    rng = np.random.default_rng(0)
    assert add_noise(true, SensorNoise(), rng) == true
    assert rng.random() == np.random.default_rng(0).random()  # no noise: no draws
    noisy = [add_noise(true, SensorNoise(range_m=0.01, torque_nm=1.0), rng) for _ in range(2000)]
    assert min(r.range_m for r in noisy) >= 0.0
    averaged = [add_noise(true, SensorNoise(torque_nm=1.0), rng, torque_samples=16).tilt_torque_nm for _ in range(2000)]
    assert np.std(averaged) == pytest.approx(0.25, rel=0.1)


def test_noise_reaches_the_state_but_not_the_metrics():
    _, clean, clean_info = started()
    _, noisy, noisy_info = started(**{"sensor.joint_noise_rad": 0.01, "sensor.range_noise_m": 0.01})
    assert not np.allclose(clean[7:9], noisy[7:9])
    assert clean_info["tip_to_pile_m"] == noisy_info["tip_to_pile_m"]
    assert clean_info["fill_factor"] == noisy_info["fill_factor"]


def test_preset_none_reproduces_the_old_environment_exactly():
    """Digests of the heuristic's observations and rewards, made with the environment before the
    ``randomize``/``sensor`` sections existed (commit 6fc3819), seeds 0-2, truth and torque mass; with
    the odometry of then (``sensor.odometry_window_steps=1``) and the heuristic's slip share of then."""
    expected = json.loads(DIGESTS.read_text())
    for key, want in expected.items():
        source, seed = key.rsplit("-", 1)
        # the odometry of then: the instantaneous wheel speed, which the heuristic's slip share was tuned to
        config = ScoopConfig().with_overrides({"env.mass_source": source, "sensor.odometry_window_steps": 1})
        assert config.randomize.preset == "none" and not config.randomize.active
        env = make_scoop_env(config)
        policy = HeuristicScooper(replace(HeuristicParams(), push_slip_fraction=0.35))
        obs, _ = env.reset(seed=int(seed))
        policy.reset()
        observations, rewards = [obs], []
        while True:
            obs, reward, terminated, truncated, _ = env.step(policy.act(obs))
            observations.append(obs)
            rewards.append(reward)
            if terminated or truncated:
                break
        digest = hashlib.sha256(np.asarray(observations, dtype=np.float32).tobytes()
                                + np.asarray(rewards).tobytes()).hexdigest()
        assert (len(rewards), digest) == (want["steps"], want["sha256"]), key
