"""The robot's node config: defaults, checked ranges with clear errors, potentiometer calibration."""

import pytest

from autoscoop.cli import main
from autoscoop.core.config import ConfigError
from autoscoop.deploy.robot_config import (
    PotentiometerCalibration,
    RobotNodeConfig,
    load_robot_config,
    robot_config_from_dict,
)


def test_defaults_match_the_paper_and_the_environment():
    c = RobotNodeConfig()
    assert (c.control.control_period_s, c.control.input_timeout_s, c.control.episode_s) == (0.25, 0.5, 8.0)
    assert (c.limits.max_speed_mps, c.limits.lift_min_rad, c.limits.lift_max_rad) == (0.1, -0.10, 0.32)
    assert (c.limits.tilt_min_rad, c.limits.tilt_max_rad) == (-0.50, 0.90)
    assert c.topics.lift_command == "lift_controller/command" and not c.topics.cmd_vel.startswith("/")


@pytest.mark.parametrize("data, fragment", [
    ({"control": {"input_timeout_s": 0}},
     "control.input_timeout_s = 0: Input should be greater than or equal to 0.02 (allowed [0.02, 5.0] s)"),
    ({"control": {"control_period_s": "fast"}}, "control.control_period_s = 'fast': Input should be a valid number"),
    ({"limits": {"max_speed_mps": 1.0}},
     "limits.max_speed_mps = 1.0: Input should be less than or equal to 0.5 (allowed [0.0, 0.5] m/s)"),
    ({"limits": {"lift_max_rad": 0.5}}, "limits.lift_max_rad"),
    ({"limits": {"tilt_min_rad": 0.5, "tilt_max_rad": 0.2}}, "must be below limits.tilt_max_rad"),
    ({"sensors": {"joint_margin_rad": float("nan")}}, "sensors.joint_margin_rad = nan: Input should be a finite number"),
    ({"sensors": {"lift_joint": "tilt"}}, "two different non-empty names"),
    ({"topics": {"cmd_vel": "cmd vel"}}, "topics.cmd_vel = 'cmd vel' is not a valid ROS name"),
    ({"topics": {"odom": "joint_states"}}, "each needs its own"),
    ({"estop": {"required": "maybe"}}, "estop.required = 'maybe': Input should be a valid boolean"),
    ({"payload": {"calibration": "/no/such.yaml"}}, "payload.calibration"),
    ({"potentiometer": {"lift": {"raw": [1, 2, 2], "rad": [0, 0.1, 0.2]}}}, "strictly increasing or strictly"),
    ({"potentiometer": {"lift": {"raw": [1, 2], "rad": [0, 0.1, 0.2]}}}, "same length"),
    ({"potentiometer": {"wrist": None}}, "lift and/or tilt"),
    ({"control": {"speed": 1}}, "unknown robot config key(s) ['control.speed']"),
    ({"motors": {}}, "unknown robot config section(s) ['motors']"),
])
def test_bad_values_name_the_key_and_what_is_allowed(data, fragment):
    with pytest.raises(ConfigError) as error:
        robot_config_from_dict(data)
    assert fragment in str(error.value)


def test_potentiometer_calibration_maps_both_ways_and_extends_the_end_segments():
    cal = PotentiometerCalibration.parse("potentiometer.lift", {"raw": [900, 500, 100], "rad": [-0.1, 0.1, 0.32]})
    assert cal.to_rad(500) == pytest.approx(0.1)
    assert cal.to_rad(300) == pytest.approx(0.21)
    assert cal.to_rad(950) == pytest.approx(-0.125)  # extended beyond the measured span
    for angle in (-0.1, 0.0, 0.17, 0.32):
        assert cal.to_rad(cal.to_raw(angle)) == pytest.approx(angle)


def test_yaml_file_round_trip_and_errors_name_the_file(tmp_path):
    good = tmp_path / "robot.yaml"
    good.write_text("control: {input_timeout_s: 0.3}\npotentiometer:\n  tilt: {raw: [0, 1023], rad: [-0.5, 0.9]}\n")
    config = load_robot_config(good)
    assert config.control.input_timeout_s == 0.3 and config.tilt_potentiometer.to_rad(1023) == pytest.approx(0.9)
    assert robot_config_from_dict(config.to_dict()) == config
    bad = tmp_path / "bad.yaml"
    bad.write_text("limits: {max_speed_mps: 2}\n")
    with pytest.raises(ConfigError, match=r"bad\.yaml: limits\.max_speed_mps"):
        load_robot_config(bad)


def test_controller_refuses_to_start_with_a_bad_config(tmp_path, capsys):
    bad = tmp_path / "robot.yaml"
    bad.write_text("control: {input_timeout_s: -1}\n")
    assert main(["ros", "controller", "--policy", "heuristic", "--robot", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "controller not started" in err and "control.input_timeout_s" in err and "allowed [0.02, 5.0]" in err


def test_controller_check_prints_the_config_without_ros(capsys):
    assert main(["ros", "controller", "--policy", "heuristic", "--check"]) == 0
    assert "control.input_timeout_s" in capsys.readouterr().out


def test_the_example_robot_config_is_valid_and_its_calibration_round_trips_through_the_simulator():
    from pathlib import Path

    from autoscoop.core.config import ScoopConfig
    from autoscoop.deploy.controller import ControllerCore
    from autoscoop.deploy.sim_bridge import SimBridge

    robot = load_robot_config(Path(__file__).parents[1] / "docs" / "robot.example.yaml")
    assert robot.lift_potentiometer is not None and robot.tilt_potentiometer is not None
    bridge = SimBridge(ScoopConfig().with_overrides({"pile.variants": 1}), robot=robot)
    readings = bridge.reset(0)
    assert readings.joint_positions[0] > 100  # raw potentiometer counts, not radians
    core = ControllerCore(robot, policy=None)
    assert core.joint_states(readings.joint_names, readings.joint_positions, 0.0)
    sim = bridge.env.unwrapped.sim
    assert (core.lift_rad, core.tilt_rad) == pytest.approx((sim.lift_rad, sim.tilt_rad), abs=1e-9)
    bridge.close()


def test_the_robot_config_is_built_on_the_shared_config_schema():
    import ast
    import inspect

    from autoscoop.core.config import ConfigModel
    from autoscoop.deploy import robot_config

    sections = [robot_config.ControlSection, robot_config.LimitsSection, robot_config.SensorsSection,
                robot_config.EstopSection, robot_config.PayloadSection, robot_config.TopicsSection,
                robot_config.PotentiometerSection, PotentiometerCalibration, RobotNodeConfig]
    assert all(issubclass(cls, ConfigModel) for cls in sections)
    assert RobotNodeConfig.from_dict.__func__ is ConfigModel.from_dict.__func__
    assert RobotNodeConfig.describe is ConfigModel.describe and RobotNodeConfig.to_dict is ConfigModel.to_dict
    imported = [alias.name for node in ast.walk(ast.parse(inspect.getsource(robot_config)))
                if isinstance(node, ast.ImportFrom) and node.module == "autoscoop.core.config" for alias in node.names]
    assert imported and not [name for name in imported if name.startswith("_")]


def test_robot_config_coerces_ints_keeps_null_sections_and_validates_replace():
    c = robot_config_from_dict({"control": None, "potentiometer": None, "limits": {"max_speed_mps": 0}})
    assert c.limits.max_speed_mps == 0.0 and type(c.limits.max_speed_mps) is float
    assert c.control == RobotNodeConfig().control and c.lift_potentiometer is None and c.potentiometer("tilt") is None
    with pytest.raises(ConfigError, match=r"limits\.lift_min_rad = 0\.32 must be below limits\.lift_max_rad"):
        c.replace(limits=c.limits.replace(lift_min_rad=0.32))
    with pytest.raises(ConfigError, match="control.input_timeout_s = 0.02 s is shorter than a tenth"):
        c.replace(control=c.control.replace(input_timeout_s=0.02))
    with pytest.raises(ConfigError, match=r"sensors\.lift_joint = 3: Input should be a valid string"):
        robot_config_from_dict({"sensors": {"lift_joint": 3}})
    with pytest.raises(ConfigError, match=r"potentiometer\.tilt\.raw = \[1\]: Tuple should have at least 2 items"):
        robot_config_from_dict({"potentiometer": {"tilt": {"raw": [1], "rad": [0, 1]}}})
    assert set(RobotNodeConfig().to_dict()) == {"control", "limits", "sensors", "estop", "payload", "topics",
                                                 "potentiometer"}
    keys = [row.split()[0] for row in RobotNodeConfig().describe().splitlines()]
    assert "topics.cmd_vel" in keys and "potentiometer.lift" in keys and len(keys) == len(set(keys))
