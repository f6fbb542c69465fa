"""The level state frame (``sensor.level_with_imu``): the arm's points turned by the IMU's chassis pitch.

The state's tip and bucket-joint positions come from the arm's kinematics in the chassis frame; a loader
rocked onto its front wheels by heavy earth has its tip far lower than they say. A policy trained with
the level frame records it in its file, and the rollout loop, the ROS controller and the ONNX export
all honour it; the paper's chassis frame stays the default, unchanged.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from autoscoop.core import kinematics
from autoscoop.core.config import ScoopConfig
from autoscoop.core.state import Measurements, build_state, level_points
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.sim.load_cell import chassis_pitch_rad


def test_a_pitch_of_zero_leaves_the_points_as_they_are():
    tip = kinematics.arm_pose(0.1, 0.2).tip
    assert level_points(tip, 0.0) is tip
    now = Measurements(mass_kg=1.0, pile_distance_m=0.1, speed_mps=0.05, lift_rad=0.1, tilt_rad=0.2)
    assert np.array_equal(build_state(now, None, 7.0),
                          build_state(Measurements(**{**now.__dict__, "chassis_pitch_rad": 0.0}), None, 7.0))


@pytest.mark.parametrize("pitch_deg", [-5.0, 5.0, 13.0])
def test_nose_down_pitch_lowers_the_tip_about_the_chassis_centre(pitch_deg):
    pitch = math.radians(pitch_deg)
    now = Measurements(mass_kg=0.0, pile_distance_m=0.1, speed_mps=0.0, lift_rad=0.0, tilt_rad=0.0,
                       chassis_pitch_rad=pitch)
    flat = build_state(Measurements(**{**now.__dict__, "chassis_pitch_rad": 0.0}), None, 7.0)
    level = build_state(now, None, 7.0)
    centre = np.array([0.0, kinematics.CHASSIS_CENTRE_HEIGHT_M])
    for index in (1, 3):  # tip, bucket joint: the same distance from the centre, turned by the pitch
        before, after = flat[index:index + 2] - centre, level[index:index + 2] - centre
        assert np.linalg.norm(after) == pytest.approx(np.linalg.norm(before), abs=1e-6)
        turned = math.atan2(before[1], before[0]) - math.atan2(after[1], after[0])
        assert turned == pytest.approx(pitch, abs=1e-5)
    # the tip lies about 1.1 m ahead of the centre: 13 deg nose down drops it by about 0.25 m
    assert np.sign(flat[2] - level[2]) == np.sign(pitch_deg)
    if pitch_deg == 13.0:
        assert 0.2 < flat[2] - level[2] < 0.3
    assert np.array_equal(flat[[0, 5, 6, 7, 8]], level[[0, 5, 6, 7, 8]])


def test_the_environment_levels_the_state_by_the_chassis_pitch_only_when_asked():
    config = ScoopConfig().with_overrides({"pile.particle_mass_kg": 0.4})
    plain, level = make_scoop_env(config), make_scoop_env(config.with_overrides({"sensor.level_with_imu": True}))
    assert plain.unwrapped.state_frame == "chassis" and level.unwrapped.state_frame == "level"
    for env in (plain, level):
        env.reset(seed=3)
    pitches = []
    for step in range(14):  # drive into the heavy pile and lift: the chassis pitches
        action = np.array([1.0, -0.3 if step > 9 else 0.0, -0.2 if step > 9 else 0.1])
        obs_plain = plain.step(action)[0]
        obs_level = level.step(action)[0]
        pitch = chassis_pitch_rad(level.unwrapped.sim)
        pitches.append(pitch)
        expected = build_state(Measurements(mass_kg=0.0, pile_distance_m=0.0, speed_mps=0.0,
                                            lift_rad=float(obs_level[7]), tilt_rad=float(obs_level[8]),
                                            chassis_pitch_rad=pitch), None, 7.0)
        np.testing.assert_allclose(obs_level[1:5], expected[1:5], atol=1e-5)
        arm = kinematics.arm_pose(float(obs_plain[7]), float(obs_plain[8]))
        np.testing.assert_allclose(obs_plain[1:3], arm.tip, atol=1e-6)  # the chassis frame: kinematics alone
    assert max(abs(p) for p in pitches) > math.radians(1.0)


def test_a_policy_file_declares_its_frame_and_the_rollout_builds_the_state_in_it(tmp_path):
    pytest.importorskip("torch")
    from autoscoop.agents.loading import PolicyError, load_policy
    from autoscoop.agents.networks import PaperActor
    from autoscoop.agents.policy_files import save_actor

    level_file = save_actor(PaperActor(), tmp_path / "level.safetensors", {"state_frame": "level"})
    old_file = save_actor(PaperActor(), tmp_path / "old.safetensors", {})  # written before the frame existed
    env = make_scoop_env(ScoopConfig())
    level, old = load_policy(str(level_file), ScoopConfig()), load_policy(str(old_file), ScoopConfig())
    assert (level.state_frame, old.state_frame) == ("level", "chassis")
    rollout(level, env, 0)
    assert env.unwrapped.state_frame == "level" and env.unwrapped.config.sensor.level_with_imu
    rollout(old, env, 0)
    assert env.unwrapped.state_frame == "chassis"
    rollout(load_policy("heuristic", ScoopConfig()), make_scoop_env(ScoopConfig()), 0)  # declares none: left alone

    sidecar = level_file.with_suffix(".json")
    sidecar.write_text(json.dumps({**json.loads(sidecar.read_text()), "state_frame": "world"}))
    with pytest.raises(PolicyError, match="state_frame 'world'"):
        load_policy(str(level_file), ScoopConfig())
    with pytest.raises(ValueError, match="state frame 'world'"):
        env.unwrapped.use_state_frame("world")


def test_the_ros_controller_levels_the_state_by_the_odometry_pitch_for_a_level_policy():
    from autoscoop.deploy.controller import ControllerCore
    from autoscoop.deploy.robot_config import RobotNodeConfig

    class Recorder:
        def __init__(self, frame):
            self.name, self.state_frame, self.states = "recorder", frame, []

        def reset(self):
            pass

        def act(self, observation):
            self.states.append(np.array(observation))
            return np.zeros(3)

    states = {}
    for frame in ("chassis", "level"):
        policy = Recorder(frame)
        core = ControllerCore(RobotNodeConfig(), policy, ScoopConfig())
        t = 0.0
        core.scoop(True, t)
        while t < 1.0:
            core.joint_states(["lift", "tilt"], [0.2, 0.1], t)
            core.odometry(0.0, t, chassis_pitch_rad=math.radians(10.0))
            core.pile_range(0.3, t, 0.0, 4.0)
            core.bucket_torque(-1.0, t)
            core.lift_torque(-20.0, t)
            core.update(t)
            t += 0.02
        assert policy.states, frame
        states[frame] = policy.states[-1]
    assert core.level_state
    assert states["chassis"][2] - states["level"][2] > 0.15  # 10 deg nose down: the tip about 0.2 m lower
    np.testing.assert_array_equal(states["chassis"][[5, 6, 7, 8]], states["level"][[5, 6, 7, 8]])


def test_the_onnx_export_carries_the_frame(tmp_path):
    pytest.importorskip("onnxruntime")
    pytest.importorskip("torch")
    from autoscoop.agents.networks import PaperActor
    from autoscoop.agents.onnx_policy import OnnxPolicy
    from autoscoop.agents.policy_files import save_actor
    from autoscoop.cli import main

    weights = save_actor(PaperActor(), tmp_path / "level.safetensors", {"state_frame": "level"})
    out = tmp_path / "level.onnx"
    assert main(["export", "--policy", str(weights), "--onnx", str(out), "--check-states", "0"]) == 0
    assert OnnxPolicy(out).state_frame == "level"


def test_the_robot_level_recipe_is_the_robot_recipe_in_the_level_frame_with_twice_the_episodes():
    pytest.importorskip("torch")
    import typing

    from autoscoop.commands.train_cmd import register
    from autoscoop.training.recipes import RECIPES
    from autoscoop.training.settings import load_recipe
    from autoscoop.training.sweep_space import SweepSpace

    robot, level = load_recipe("ddpg", "robot"), load_recipe("ddpg", "robot_level")
    assert (robot["episodes"], level["episodes"]) == (2500, 5000)
    assert level["env"] == {**robot["env"], "sensor.level_with_imu": True}
    assert {k: v for k, v in level.items() if k not in ("episodes", "env", "recipe")} == \
        {k: v for k, v in robot.items() if k not in ("episodes", "env", "recipe")}
    # every named recipe is a choice of `autoscoop train --recipe` and of a sweep's space
    import argparse
    parser = argparse.ArgumentParser()
    register(parser.add_subparsers())
    for name in RECIPES:
        assert parser.parse_args(["train", "--recipe", name]).recipe == name
    assert set(typing.get_args(SweepSpace.model_fields["recipe"].annotation)) == set(RECIPES)


def test_the_shipped_recipe_is_robot_level_with_a_sharper_progress_term_and_a_flip_cost():
    pytest.importorskip("torch")
    from autoscoop.core.config import ScoopConfig
    from autoscoop.training.settings import load_recipe

    level, smooth = load_recipe("ddpg", "robot_level"), load_recipe("ddpg", "robot_smooth")
    assert smooth["env"] == {**level["env"], "reward.distance_scale_m": 0.3, "reward.c_action_change": 1.0}
    assert {k: v for k, v in smooth.items() if k not in ("env", "recipe")} == \
        {k: v for k, v in level.items() if k not in ("env", "recipe")}
    # the two options are off in the paper's world
    assert (ScoopConfig().reward.distance_scale_m, ScoopConfig().reward.c_action_change) == (1.0, 0.0)


def test_the_ros_simulator_reads_the_imu_pitch_with_the_joints_noise_and_only_then():
    """`autoscoop ros sim` with noise reads the pitch as the environment does (the joints' std); the other
    readings draw the same noise as before (the IMU has a stream of its own)."""
    from autoscoop.core.payload import pitch_from_quaternion
    from autoscoop.core.sensing import SensorNoise
    from autoscoop.deploy.sim_bridge import SimBridge

    config = ScoopConfig().with_overrides({"pile.variants": 1})
    exact, noisy, joints_only = (SimBridge(config, noise=noise, seed=3) for noise in (
        SensorNoise(), SensorNoise(joint_rad=0.01), SensorNoise(joint_rad=0.01)))
    errors = []
    for bridge in (exact, noisy, joints_only):
        bridge.reset(seed=0)
    for _ in range(60):
        truth, read, again = (bridge.step(np.array([0.1, 0.3, 0.1])) for bridge in (exact, noisy, joints_only))
        true_pitch = pitch_from_quaternion(*truth.chassis_quat_wxyz)
        errors.append(pitch_from_quaternion(*read.chassis_quat_wxyz) - true_pitch)
        assert read.joint_positions == again.joint_positions  # same seed, same draws
        assert np.linalg.norm(read.chassis_quat_wxyz) == pytest.approx(1.0)
    errors = np.array(errors)
    assert 0.006 < errors.std() < 0.014
    assert abs(errors.mean()) < 0.005
    steady = SimBridge(config, seed=3)
    steady.reset(seed=0)
    assert steady.readings().chassis_quat_wxyz == steady.readings().chassis_quat_wxyz  # no noise: the truth
