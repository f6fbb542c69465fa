"""The ROS 2 nodes over Cyclone DDS, on the loopback interface only, in a DDS domain of their own.

Names, QoS and the domain are checked without DDS; then the controller runs in this process against
a stand-in robot (its watchdog, a latched e-stop), and ``ros2 sim`` and ``ros2 controller`` run as two
processes for one scoop. Skipped where the ``ros2`` extra is not installed.
"""

import json
import os
import random
import subprocess
import sys
import threading
import time
from pathlib import Path

import forked
import pytest

pytest.importorskip("cyclonedds")
pytest.importorskip("mcap_ros2")  # the recordings' checks; the ros2 extra brings both

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ConfigError, ScoopConfig
from autoscoop.deploy.controller import ControllerCore
from autoscoop.deploy.robot_config import RobotNodeConfig
from autoscoop.deploy.ros2.controller_node import ControllerNode
from autoscoop.deploy.ros2.graph import (
    COMMANDS,
    LATCHED,
    LOOPBACK_CONFIG,
    SENSOR_DATA,
    TOPIC_QOS,
    Ros2Node,
    domain_id,
    expand_name,
    parse_remaps,
    take_all,
)
from autoscoop.deploy.ros2.messages import Bool, String, Twist
from autoscoop.deploy.ros2.sim_node import SENSOR_TOPICS, sensor_messages
from autoscoop.deploy.sim_bridge import SensorReadings
from autoscoop.envs.records import load_record

ROBOT_EXAMPLE = str(Path(__file__).resolve().parents[1] / "docs" / "robot.example.yaml")
"""The README's robot file: both joints read as raw potentiometer readings."""
DOMAIN = random.Random().randint(100, 199)
"""A domain of this test run's own: two runs at once do not hear each other."""
CONFIG = RobotNodeConfig()
PERIOD, TIMEOUT = CONFIG.control.control_period_s, CONFIG.control.input_timeout_s
STILL = SensorReadings(0.0, ("lift", "tilt"), (0.23, 0.0), 0.0, 0.3, -1.0, -20.0, 0.0, (0.0, 0.0, 0.13),
                       (1.0, 0.0, 0.0, 0.0))


@pytest.fixture(scope="module", autouse=True)
def loopback_domain():
    saved = {key: os.environ.get(key) for key in ("CYCLONEDDS_URI", "ROS_DOMAIN_ID")}
    os.environ.update(CYCLONEDDS_URI=LOOPBACK_CONFIG, ROS_DOMAIN_ID=str(DOMAIN))
    yield
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


# ---------------------------------------------------------------- names, QoS, domain (no DDS)
def test_names_resolve_as_in_ros2():
    assert expand_name("joint_states", "/", "n") == "/joint_states"
    assert expand_name("lift_controller/command", "/loader1", "n") == "/loader1/lift_controller/command"
    assert expand_name("~/status", "/loader1", "autoscoop_controller") == "/loader1/autoscoop_controller/status"
    assert expand_name("/odom", "/loader1", "n") == "/odom"
    remaps, namespace, node = parse_remaps(["joint_states:=sensors/joints", "__ns:=/e2e", "__node:=ctl"])
    assert (remaps, namespace, node) == ({"joint_states": "sensors/joints"}, "/e2e", "ctl")
    with pytest.raises(ConfigError, match="private parameters"):
        parse_remaps(["_rate:=5"])


def test_qos_profiles_follow_ros2():
    from cyclonedds.core import Policy

    assert Policy.Reliability.BestEffort in SENSOR_DATA and Policy.History.KeepLast(5) in SENSOR_DATA
    assert COMMANDS[Policy.Reliability].__scope__ == LATCHED[Policy.Reliability].__scope__ == "Reliability"
    assert Policy.Durability.TransientLocal in LATCHED and Policy.Durability.Volatile in COMMANDS
    assert TOPIC_QOS["estop"] is LATCHED and TOPIC_QOS["cmd_vel"] is COMMANDS and TOPIC_QOS["odom"] is SENSOR_DATA
    assert Policy.Reliability.BestEffort not in COMMANDS


def test_ros_domain_id_is_honoured_and_checked():
    assert domain_id({}) == 0 and domain_id({"ROS_DOMAIN_ID": "17"}) == 17
    for bad in ("-1", "233", "x"):
        with pytest.raises(ConfigError, match="ROS_DOMAIN_ID"):
            domain_id({"ROS_DOMAIN_ID": bad})
    node = Ros2Node("probe")
    try:
        assert node.domain == DOMAIN and node.participant.domain_id == DOMAIN
    finally:
        node.close()


def test_nodes_in_another_domain_are_not_heard():
    talker, same, other = Ros2Node("talker"), Ros2Node("same"), Ros2Node("other", domain=DOMAIN + 1)
    try:
        writer = talker.publisher("chatter", Bool, COMMANDS)
        readers = [node.subscription("chatter", Bool, COMMANDS) for node in (same, other)]
        assert talker.wait_for_subscriber(writer, 10.0)
        time.sleep(1.0)  # time for the other domain's reader to be found, were it visible
        assert writer.get_publication_matched_status().current_count == 1
        writer.write(Bool(True))
        assert wait_for(lambda: take_all(readers[0], Bool), 2.0) and not take_all(readers[1], Bool)
    finally:
        for node in (talker, same, other):
            node.close()


def test_a_bad_domain_is_a_usage_error():
    run = forked.run([sys.executable, "-m", "autoscoop.cli", "ros2", "controller", "--policy", "heuristic"],
                     env=dict(os.environ, ROS_DOMAIN_ID="999"), capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and "ROS_DOMAIN_ID" in run.stderr, run.stdout + run.stderr


# ---------------------------------------------------------------- the controller against a stand-in robot
class StandIn:
    """The robot's sensors at 50 Hz (still readings, freshly stamped) and a record of ``cmd_vel``."""

    def __init__(self, namespace):
        self.node = node = Ros2Node("stand_in", namespace=namespace)
        topics = CONFIG.topics
        self.writers = {key: node.publisher(getattr(topics, key), type(msg), TOPIC_QOS[key])
                        for key, msg in sensor_messages(STILL, 1.0) if key in SENSOR_TOPICS}
        self.scoop = node.publisher(topics.scoop, Bool, COMMANDS)
        self.speeds = []
        node.subscription(topics.cmd_vel, Twist, COMMANDS,
                          lambda msg: self.speeds.append((time.monotonic(), msg.linear.x)))
        self.silent = threading.Event()
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._play, daemon=True)
        self.thread.start()

    def _play(self):
        while not self.done.wait(0.02):
            if not self.silent.is_set():
                for key, msg in sensor_messages(STILL, time.time()):
                    self.writers[key].write(msg)

    def moving_since(self, since):
        return any(t >= since and v > 0 for t, v in self.speeds)

    def close(self):
        self.done.set()
        self.thread.join()
        self.node.close()


def start_controller(namespace):
    task = ScoopConfig()
    core = ControllerCore(CONFIG, load_policy("heuristic", task), task, policy_name="heuristic")
    node = ControllerNode(core, namespace=namespace)
    thread = threading.Thread(target=node.spin, daemon=True)
    thread.start()
    return node, thread


def wait_for(condition, timeout_s):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.01)
    return False


def test_controller_drives_stops_when_silenced_and_obeys_a_latched_estop():
    robot = StandIn("/probe")
    node, thread = start_controller("/probe")
    try:
        assert robot.node.wait_for_subscriber(robot.scoop, 10.0), "controller never subscribed to scoop"
        time.sleep(0.3)
        robot.scoop.write(Bool(True))
        assert wait_for(lambda: robot.moving_since(0.0), 5.0), "controller never drove"

        robot.silent.set()  # the watchdog: every sensor falls silent
        silenced = time.monotonic()
        assert wait_for(lambda: robot.speeds and robot.speeds[-1][1] == 0.0 and robot.speeds[-1][0] > silenced,
                        TIMEOUT + 2 * PERIOD)
        stopped_after = robot.speeds[-1][0] - silenced
        assert stopped_after <= TIMEOUT + PERIOD, stopped_after
        robot.silent.clear()
        resumed = time.monotonic()
        assert wait_for(lambda: robot.moving_since(resumed), 3.0), "did not resume"

        # an e-stop latched by a publisher that has since gone quiet reaches the controller
        estop_node = Ros2Node("estop_button", namespace="/probe")
        estop_node.publisher(CONFIG.topics.estop, Bool, LATCHED).write(Bool(True))
        engaged = time.monotonic()
        assert wait_for(lambda: robot.speeds[-1][0] > engaged and robot.speeds[-1][1] == 0.0, 2.0)
        time.sleep(3 * PERIOD)
        assert not robot.moving_since(engaged + 0.5), "drove while the e-stop was engaged"
        status = robot.node.subscription("autoscoop_controller/status", String, LATCHED)
        assert wait_for(lambda: any("estop" in m.data for m in take_all(status, String)), 2.0)
        estop_node.close()
    finally:
        node.stop()
        thread.join(timeout=10)
        robot.close()
    assert not thread.is_alive()


# ---------------------------------------------------------------- the two nodes as their own processes
def test_sim_and_controller_scoop_over_ros2_in_a_namespace_with_remapped_topics(tmp_path):
    remap = "joint_states:=sensors/joints"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    controller = forked.Popen([sys.executable, "-m", "autoscoop.cli", "ros2", "controller", "--policy",
                               "heuristic", "--records", str(tmp_path / "robot"), "--bag",
                               str(tmp_path / "controller.mcap"), "__ns:=/e2e", remap],
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    out = tmp_path / "ros2_sim.json"
    try:
        sim = forked.run([sys.executable, "-m", "autoscoop.cli", "ros2", "sim", "--episodes", "1", "--json",
                          str(out), "--set", "pile.variants=1", "--joint-noise-rad", "0.001", "--wait-s", "60",
                          "--bag", str(tmp_path / "sim.mcap"), "__ns:=/e2e", remap], env=env,
                         capture_output=True, text=True, timeout=120)
    finally:
        controller.terminate()  # SIGTERM: the node stops the robot, writes its record and leaves
        log, _ = controller.communicate(timeout=20)
    assert controller.returncode == 0 and "Traceback" not in log, log[-3000:]
    assert sim.returncode == 0, sim.stdout[-3000:] + sim.stderr[-3000:] + log[-3000:]
    summary = json.loads(out.read_text())
    assert summary["policy"] == "heuristic" and summary["episodes"] == 1  # the controller's latched policy name
    (episode,) = summary["episodes_detail"]
    assert episode["fill_factor"] > 0.2 and not episode["physics_error"], summary
    assert summary["ros"]["real_time_factor"] > 0.5
    records = sorted((tmp_path / "robot").glob("*.npz"))
    assert records and len(load_record(records[0])) >= 5, log[-3000:]

    check_recordings_and_replay(tmp_path)


def check_recordings_and_replay(folder):
    """Both recordings open with rosbags and with mcap's ROS 2 decoder and replay; replaying the controller's log
    with the same policy reproduces the commands sent."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader

    for name in ("controller", "sim"):
        path = folder / f"{name}.mcap"
        with AnyReader([path]) as reader:
            types = {c.topic: c.msgtype for c in reader.connections}
            assert types["/e2e/sensors/joints"] == "sensor_msgs/msg/JointState" and types["/e2e/odom"] == "nav_msgs/msg/Odometry"
            first = next(reader.messages([c for c in reader.connections if c.topic == "/e2e/odom"]))
            assert reader.deserialize(first[2], "nav_msgs/msg/Odometry").header.stamp.sec > 0
        with open(path, "rb") as stream:
            decoded = list(make_reader(stream, decoder_factories=[DecoderFactory()]).iter_decoded_messages())
        topics = {channel.topic for _, channel, _, _ in decoded}
        assert {"/e2e/cmd_vel", "/e2e/scoop", "/e2e/lift_controller/command"} <= topics
        assert any(ch.topic == "/e2e/pile_range" and 0 < m.range < 4 for _, ch, _, m in decoded)

        out = folder / f"replay_{name}"
        run = forked.run([sys.executable, "-m", "autoscoop.cli", "replay", str(path), "--policy", "heuristic",
                          "--namespace", "/e2e", "--set", "pile.variants=1", "--robot", str(remapped_config(folder)),
                          "--out", str(out), "--json", str(out / "summary.json")],
                         capture_output=True, text=True, timeout=120)
        assert run.returncode == 0, run.stdout + run.stderr
        summary = json.loads((out / "summary.json").read_text())
        assert summary["schedule"] == "recorded" and summary["verdicts"]["running"] >= 5, summary
        if name == "controller":  # its inputs and commands on its own clock: the same policy sends the same
            # (the simulator's log has the inputs as it sent them and the commands as they arrived, a control
            # period late or not as the machine's load has it: docs/robot.md promises the controller's log)
            assert all(v is not None and v <= 1e-6 for v in summary["max_difference"].values()), (name, summary)
        assert (out / "replay.csv").read_text().startswith("time_s,sent_speed_mps") and (out / "replay.png").stat().st_size


def remapped_config(folder):
    """A robot YAML whose joint_states is the remapped name the e2e test used."""
    path = folder / "robot.yaml"
    path.write_text("topics:\n  joint_states: sensors/joints\n")
    return path


# ---------------------------------------------------------------- the README's pair, in the robot's units
def test_the_readme_pair_scoops_in_raw_readings_refuses_a_simulator_in_radians_and_replays_from_its_bag(tmp_path):
    """`ros2 controller --robot docs/robot.example.yaml --bag` with `ros2 sim --robot` the same file: the
    simulator publishes raw potentiometer readings and the shipped policy scoops; a simulator without the
    file (radians) is refused before its first scoop; the README's `replay` takes the robot file from the bag."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    cli = [sys.executable, "-m", "autoscoop.cli"]
    bag = tmp_path / "robot.mcap"
    controller = forked.Popen([*cli, "ros2", "controller", "--policy", "default", "--robot", ROBOT_EXAMPLE,
                               "--bag", str(bag)], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              text=True)
    out = tmp_path / "ros2.json"
    try:
        radians = forked.run([*cli, "ros2", "sim", "--episodes", "1", "--wait-s", "60"], env=env,
                             capture_output=True, text=True, timeout=120)
        raw = forked.run([*cli, "ros2", "sim", "--robot", ROBOT_EXAMPLE, "--episodes", "1", "--set",
                          "pile.variants=1", "--json", str(out), "--wait-s", "60"], env=env,
                         capture_output=True, text=True, timeout=120)
    finally:
        controller.terminate()
        log, _ = controller.communicate(timeout=20)
    assert radians.returncode == 2, radians.stdout[-2000:] + radians.stderr[-2000:]
    assert "raw potentiometer readings" in radians.stderr and "--robot FILE" in radians.stderr, radians.stderr
    assert raw.returncode == 0, raw.stdout[-3000:] + raw.stderr[-3000:] + log[-3000:]
    (episode,) = json.loads(out.read_text())["episodes_detail"]
    assert episode["fill_factor"] >= 0.5 and episode["success"], episode

    replay = tmp_path / "replay"
    run = subprocess.run([*cli, "replay", str(bag), "--policy", "default", "--out", str(replay), "--json",
                          str(replay / "summary.json")], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    summary = json.loads((replay / "summary.json").read_text())
    assert summary["robot_file"].startswith("/autoscoop_controller/robot") and summary["verdicts"]["running"] >= 5
    assert all(v is not None and v <= 1e-6 for v in summary["max_difference"].values()), summary
