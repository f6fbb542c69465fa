"""``autoscoop replay``: logs read in each format, checked (missing topics, wrong types, no stamps), replayed.

Logs are made here: a stand-in robot's readings and the commands of the core itself (the ``own``
schedule), written to MCAP with :class:`McapLog`, and converted to a ROS 1 bag and a ROS 2 bag folder
with ``rosbags``. The live round trip (``ros2 controller --record`` then replay) is in test_ros2_nodes.py.
"""

import math

import pytest

pytest.importorskip("cyclonedds")
pytest.importorskip("rosbags")
pytest.importorskip("mcap")

from rosbags.rosbag1 import Writer as Bag1Writer
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Bag2Writer
from rosbags.typesys import Stores, get_typestore

from autoscoop.agents.loading import load_policy
from autoscoop.cli import main
from autoscoop.core.config import ScoopConfig
from autoscoop.deploy.controller import ControllerCore
from autoscoop.deploy.replay import LogError, Replay, differences, read_log
from autoscoop.deploy.robot_config import RobotNodeConfig
from autoscoop.deploy.ros2.mcap_log import McapLog
from autoscoop.deploy.ros2.messages import Bool, Float64, Twist, Vector3
from autoscoop.deploy.ros2.sim_node import sensor_messages
from autoscoop.deploy.sim_bridge import SensorReadings

CONFIG = RobotNodeConfig()
NEEDED = ("joint_states", "odom", "pile_range", "bucket_torque", "lift_torque", "scoop")
START_NS = 1_750_000_000 * 10**9
SENSOR_PERIOD_NS = 20_000_000


def reading(step):
    """A robot creeping towards the pile, the arm still."""
    return SensorReadings(step * 0.02, ("lift", "tilt"), (0.23, 0.0), 0.05, max(0.05, 0.6 - 0.001 * step), -1.0,
                          -20.0, 0.0, (0.001 * step, 0.0, 0.13), (1.0, 0.0, 0.0, 0.0))


def core(policy="heuristic"):
    task = ScoopConfig()
    made = ControllerCore(CONFIG, load_policy(policy, task), task, policy_name=policy)
    made.log = lambda level, text: None
    return made


def write_log(path, steps=150, silent=range(0), stamps=True, skip=(), wrong_type=None):
    """A log of ``steps`` sensor periods: readings (none in ``silent``), scoop true at step 5, and the commands
    the heuristic makes on its own schedule, written as the controller would log them."""
    log = McapLog(path)
    messages = []
    for step in range(steps):
        t = START_NS + step * SENSOR_PERIOD_NS
        if step not in silent:
            for key, message in sensor_messages(reading(step), t / 1e9 if stamps else 0.0):
                if key != "payload_mass":
                    messages.append((t, key, message))
        if step == 5:
            messages.append((t + 1, "scoop", Bool(True)))
    for t, key, message in messages:
        if key in skip:
            continue
        if key == wrong_type:
            message = Float64(1.0)
        log.write("/" + getattr(CONFIG.topics, key), message, t)
    log.close()
    if not stamps or skip or wrong_type:
        return
    rows = Replay(core()).run(read_log(path, CONFIG.topics, NEEDED), "own")
    log = McapLog(path)  # again, with the commands the controller sent
    commands = []
    for row in rows:
        t = START_NS + int(round(row.time_s * 1e9))
        commands.append((t, "cmd_vel", Twist(linear=Vector3(x=row.speed_mps))))
        if not math.isnan(row.lift_rad):
            commands += [(t, "lift_command", Float64(row.lift_rad)), (t, "tilt_command", Float64(row.tilt_rad))]
    for t, key, message in sorted(messages + commands, key=lambda item: item[0]):
        log.write("/" + getattr(CONFIG.topics, key), message, t)
    log.close()


@pytest.fixture(scope="module")
def mcap_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("logs") / "robot.mcap"
    write_log(path, silent=range(60, 100))
    return path


def convert(source, target, ros1):
    """The same log as a ROS 1 bag (``ros1``) or a ROS 2 bag folder, through rosbags."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    from rosbags.highlevel import AnyReader

    with AnyReader([source]) as reader:
        writer = Bag1Writer(target) if ros1 else Bag2Writer(target, version=8, storage_plugin=StoragePlugin.SQLITE3)
        with writer:
            connections = {}
            for c in reader.connections:
                connections[c.id] = writer.add_connection(c.topic, c.msgtype, typestore=store)
            for c, t, raw in reader.messages():
                message = reader.deserialize(raw, c.msgtype)
                data = store.serialize_ros1(message, c.msgtype) if ros1 else store.serialize_cdr(message, c.msgtype)
                writer.write(connections[c.id], t, bytes(data))


def test_the_same_policy_reproduces_the_logged_commands_in_every_format(mcap_log, tmp_path):
    convert(mcap_log, tmp_path / "robot.bag", ros1=True)
    convert(mcap_log, tmp_path / "robot_ros2", ros1=False)
    results = {}
    for path in (mcap_log, tmp_path / "robot.bag", tmp_path / "robot_ros2"):
        rows = Replay(core()).run(read_log(path, CONFIG.topics, NEEDED), "recorded")
        assert max(differences(rows).values()) <= 1e-6, path
        results[path.name] = [(r.time_s, r.speed_mps, r.lift_rad, r.mode) for r in rows]
        modes = [r.mode for r in rows]
        assert "running" in modes and "fault" in modes  # the silent spell stopped the robot, and it resumed
        assert modes.index("fault") < len(modes) - 1 - modes[::-1].index("running")
    assert len({str(v) for v in results.values()}) == 1  # the same rows from each format


def test_another_policy_differs_and_the_cli_writes_csv_figure_and_summary(mcap_log, tmp_path, capsys):
    assert main(["replay", str(mcap_log), "--policy", "default", "--out", str(tmp_path), "--json",
                 str(tmp_path / "s.json")]) == 0
    import json

    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["max_difference"]["tilt_rad"] > 1e-3 and summary["verdicts"]["fault"] >= 1
    lines = (tmp_path / "replay.csv").read_text().splitlines()
    assert lines[0].split(",")[:2] == ["time_s", "sent_speed_mps"] and len(lines) == summary["updates"] + 1
    assert (tmp_path / "replay.png").stat().st_size > 10_000


@pytest.mark.parametrize("case, named", [
    ({"skip": ("odom",)}, "no topic /odom (topics.odom"),
    ({"wrong_type": "pile_range"}, "/pile_range (topics.pile_range) is std_msgs/msg/Float64, expected sensor_msgs/msg/Range"),
    ({"stamps": False}, "carries no header stamps"),
])
def test_a_log_it_cannot_use_is_a_clear_error(case, named, tmp_path, capsys):
    path = tmp_path / "bad.mcap"
    write_log(path, steps=20, **case)
    with pytest.raises(LogError, match=named.replace("(", r"\(").replace(")", r"\)")):
        read_log(path, CONFIG.topics, NEEDED)
    assert main(["replay", str(path), "--policy", "heuristic", "--out", str(tmp_path / "out")]) == 2
    assert named in capsys.readouterr().err


def test_not_a_log_and_no_commands_are_clear_errors(mcap_log, tmp_path, capsys):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file")
    assert main(["replay", str(junk), "--policy", "heuristic", "--out", str(tmp_path / "o")]) == 2
    assert "not a readable" in capsys.readouterr().err
    sensors_only = tmp_path / "sensors.mcap"
    write_log(sensors_only, steps=20, skip=("cmd_vel",))
    assert main(["replay", str(sensors_only), "--policy", "heuristic", "--schedule", "recorded",
                 "--out", str(tmp_path / "o")]) == 2
    assert "--schedule own" in capsys.readouterr().err
    assert main(["replay", str(sensors_only), "--policy", "heuristic", "--out", str(tmp_path / "o")]) == 0


def test_a_replay_whose_every_update_is_a_fault_exits_3_unless_allowed(mcap_log, tmp_path, capsys):
    """The log's joints are in radians; a robot file that calibrates raw potentiometer readings reads them as
    far outside the joints' range, so every update stops the robot: nothing was replayed."""
    from pathlib import Path

    raw_robot = Path(__file__).resolve().parents[1] / "docs" / "robot.example.yaml"
    argv = ["replay", str(mcap_log), "--policy", "heuristic", "--robot", str(raw_robot), "--out", str(tmp_path / "o")]
    assert main(argv) == 3
    err = capsys.readouterr().err
    assert "every update was a fault" in err and "outside" in err and "--robot FILE" in err, err
    assert main([*argv, "--allow-empty"]) == 0


def test_without_robot_the_replay_takes_the_robot_file_the_log_keeps(tmp_path, capsys):
    """A log that keeps the robot file (``~/robot``) is read with it: here one that renames the odometry topic."""
    from rosbags.highlevel import AnyReader

    from autoscoop.deploy.robot_config import robot_config_from_dict, robot_yaml
    from autoscoop.deploy.ros2.messages import MESSAGE_TYPES, String

    source = tmp_path / "plain.mcap"
    write_log(source, steps=60)
    renamed = tmp_path / "renamed.mcap"
    robot = robot_config_from_dict({"topics": {"odom": "wheel_odom"}})
    log = McapLog(renamed)
    log.write("/autoscoop_controller/robot", String(robot_yaml(robot)), START_NS - 1)
    with AnyReader([source]) as reader:
        for connection, t, raw in reader.messages():
            key = next(k for k in MESSAGE_TYPES if connection.topic == "/" + getattr(CONFIG.topics, k))
            message = MESSAGE_TYPES[key].deserialize(bytes(raw))
            topic = "/wheel_odom" if key == "odom" else connection.topic
            log.write(topic, message, t)
    log.close()
    out = tmp_path / "out"
    assert main(["replay", str(renamed), "--policy", "heuristic", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "robot file /autoscoop_controller/robot of the log" in printed, printed
    assert (out / "robot.yaml").read_text() == robot_yaml(robot)
    assert main(["replay", str(renamed), "--policy", "heuristic", "--robot", str(out / "robot.yaml"),
                 "--out", str(tmp_path / "again")]) == 0
    assert main(["replay", str(source), "--policy", "heuristic", "--out", str(tmp_path / "plain")]) == 0
    assert "robot file built-in (the log keeps none)" in capsys.readouterr().out
