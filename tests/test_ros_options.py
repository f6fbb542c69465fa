"""The ROS, replay and export commands' options: the robot file is ``--robot`` wherever it is read, a recorded
bag ``--bag``, a folder of episode records ``--records``; the old spellings are refused, naming the new one."""

import pytest

from autoscoop.cli import main


@pytest.mark.parametrize("command, old, named", [
    (["ros", "controller"], "--robot-config", "--robot FILE"),
    (["ros", "controller"], "--config", "the robot file is --robot FILE"),
    (["ros", "controller"], "--record", "--records DIR"),
    (["ros2", "controller"], "--robot-config", "--robot FILE"),
    (["ros2", "controller"], "--config", "the robot file is --robot FILE"),
    (["ros2", "controller"], "--record", "--records DIR"),
    (["ros", "sim"], "--robot-config", "--robot FILE"),
    (["ros2", "sim"], "--robot-config", "--robot FILE"),
    (["ros2", "sim"], "--record", "--bag FILE.mcap"),
    (["replay", "out/robot.mcap"], "--config", "the robot file is --robot FILE"),
    (["replay", "out/robot.mcap"], "--robot-config", "--robot FILE"),
])
def test_an_old_spelling_is_refused_naming_the_new_one(command, old, named, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([*command, old, str(tmp_path / "x")])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert f"{old} is no longer an option here" in err and named in err, err


def test_the_robot_file_is_robot_on_every_node_and_the_scene_is_config_on_the_simulators(tmp_path, capsys):
    robot = tmp_path / "robot.yaml"
    robot.write_text("limits: {max_speed_mps: 0.05}\n")
    assert main(["ros", "controller", "--policy", "heuristic", "--robot", str(robot), "--check"]) == 0
    assert "limits.max_speed_mps" in capsys.readouterr().out
    assert main(["ros2", "controller", "--policy", "heuristic", "--robot", str(robot), "--check"]) == 0
    from autoscoop.cli import build_parser

    parser = build_parser()
    for node in (["ros", "sim"], ["ros2", "sim"]):
        args = parser.parse_args([*node, "--robot", str(robot), "--config", str(tmp_path / "scene.yaml")])
        assert args.robot == robot and args.config == tmp_path / "scene.yaml"
    args = parser.parse_args(["ros2", "controller", "--bag", "x.mcap", "--records", "r"])
    assert str(args.bag) == "x.mcap" and str(args.records) == "r"
    args = parser.parse_args(["ros2", "sim", "--bag", "x.mcap"])
    assert str(args.bag) == "x.mcap"
    args = parser.parse_args(["replay", "x.mcap", "--robot", str(robot)])
    assert args.robot == robot
