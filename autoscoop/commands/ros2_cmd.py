"""``autoscoop ros2 controller|sim``: the controller and the simulator as ROS 2 nodes, over Cyclone DDS.

The same nodes as ``autoscoop ros`` (the same controller core, watchdog and limits, the same simulator
and robot YAML) on ROS 2 topics: DDS topics ``rt/<namespace>/<name>``, ROS 2 type names and QoS
(sensor data best effort, keep last 5; commands reliable; the e-stop reliable and transient-local),
in the DDS domain ``ROS_DOMAIN_ID`` (default 0). No rclpy needed: the ``ros2`` extra
(``pip install 'autoscoop[ros2]'``) brings Cyclone DDS; they talk to ROS 2 nodes on rmw_cyclonedds_cpp.

Names are relative to the namespace (``__ns:=/loader1`` or ``ROS_NAMESPACE``); remap them with
``from:=to`` after the options, e.g. ``autoscoop ros2 controller --policy default joint_states:=/komodo/joint_states``.

The controller is not a substitute for the robot's hardware emergency stop.
"""

from __future__ import annotations

import argparse
import signal
from collections.abc import Callable
from pathlib import Path

from autoscoop.commands import check_output_dir, check_output_file, options
from autoscoop.commands.ros_cmd import (
    add_controller_options,
    add_records_option,
    add_sim_options,
    checked_controller,
    simulate,
)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("ros2", help="ROS 2 nodes (Cyclone DDS): the controller on the robot, the simulator",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    nodes = parser.add_subparsers(dest="node", metavar="NODE", required=True)

    controller = nodes.add_parser("controller", help="run a policy on the robot's ROS 2 topics, with watchdog and limits",
                                  description=_CONTROLLER_DOC, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_controller_options(controller)
    add_records_option(controller)
    add_bag_option(controller, "every input as the controller took it and every command it sent, on its own clock "
                               "(autoscoop replay reproduces the commands from it)")
    controller.add_argument("remap", nargs="*", type=ros2_remap, metavar="FROM:=TO",
                            help="ROS 2 remappings; __ns:=/NAMESPACE and __node:=NAME set the namespace and the name")
    controller.set_defaults(func=run_controller)

    sim = nodes.add_parser("sim", help="the MuJoCo scene behind the robot's ROS 2 topics (like Gazebo)",
                           description=_SIM_DOC, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_sim_options(sim)
    add_bag_option(sim, "every sensor message and scoop flag as published, every command as it arrived")
    options.retire_option(sim, "--record", "the recorded bag is --bag FILE.mcap")
    sim.add_argument("remap", nargs="*", type=ros2_remap, metavar="FROM:=TO",
                     help="ROS 2 remappings; __ns:=/NAMESPACE sets the namespace")
    sim.set_defaults(func=run_sim)


_CONTROLLER_DOC = """Run a policy on the robot through ROS 2 (Cyclone DDS, no rclpy).

The topics, types and safety of `autoscoop ros controller`, with ROS 2's QoS: joint_states, odom,
pile_range, bucket_torque, lift_torque, payload_mass in (best effort, keep last 5); estop in (reliable;
transient-local publishers are heard too, with their latched value); scoop in, cmd_vel,
lift_controller/command, tilt_controller/command out (reliable, keep last 10); ~/status and ~/policy
out (std_msgs/String, latched). Stamps are judged on the system clock (ROS 2 time).

Every command is clamped to the configured limits. Any input older than control.input_timeout_s, or
not finite, or out of range -> zero velocity and the arm held, until the inputs are healthy again;
estop true -> the same until estop false. Not a substitute for the hardware emergency stop.
"""

_SIM_DOC = """The simulator as a ROS 2 node (Cyclone DDS): publishes joint_states, odom, pile_range,
bucket_torque, lift_torque and payload_mass (best effort, with noise and delay as configured) in real
time, obeys cmd_vel and the joint commands, and starts each episode on the scoop topic (reliable).
--episodes N --json OUT writes the summary of `autoscoop eval`.
"""


def add_bag_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--bag FILE.mcap``: the node's topics as a ROS 2 bag (MCAP, CDR, ROS 2 schemas)."""
    parser.add_argument("--bag", type=mcap_path, metavar="FILE",
                        help=f"record the node's topics to this MCAP file (a ROS 2 bag): {what}")


def mcap_path(text: str) -> Path:
    """``type=`` of ``--bag``: a path ending in ``.mcap``."""
    if not text.endswith(".mcap"):
        raise argparse.ArgumentTypeError(f"{text!r}: the recording is an MCAP file, its name ends in .mcap")
    return Path(text)


def _mcap_log(path: Path | None):
    """The MCAP log of ``--bag`` (checked writable first), or ``None``."""
    if path is None:
        return None
    check_output_file(path, "--bag")
    from autoscoop.deploy.ros2.mcap_log import McapLog  # noqa: PLC0415

    return McapLog(path)


def ros2_remap(text: str) -> str:
    """``type=`` of the arguments after the options: ROS 2 remappings ``FROM:=TO`` only."""
    if ":=" not in text or text.startswith(":=") or text.endswith(":="):
        raise argparse.ArgumentTypeError(f"unexpected {text!r}: only ROS 2 remappings FROM:=TO may follow the options")
    return text


def _stop_on_sigterm(stop: Callable[[], None]) -> None:
    """SIGTERM (a launcher, a service manager, a test) stops the node as Ctrl-C does: the robot is
    stopped, the scoop's record written, the DDS participant deleted."""
    signal.signal(signal.SIGTERM, lambda signum, frame: stop())


def _domain_checked() -> None:
    """ROS_DOMAIN_ID checked before anything starts (a ConfigError, exit 2, naming it)."""
    from autoscoop.deploy.ros2 import require_ros2  # noqa: PLC0415

    require_ros2()
    from autoscoop.deploy.ros2.graph import domain_id  # noqa: PLC0415

    domain_id()


def run_controller(args: argparse.Namespace) -> int:
    if args.records:
        check_output_dir(args.records, "--records")
    if args.bag:
        check_output_file(args.bag, "--bag")
    core = checked_controller(args, args.records)
    if core is None:
        return 0
    from autoscoop.deploy.ros2 import Ros2Unavailable  # noqa: PLC0415

    try:
        _domain_checked()
        from autoscoop.deploy.ros2.controller_node import ControllerNode  # noqa: PLC0415

        node = ControllerNode(core, args.remap, log=_mcap_log(args.bag))
        _stop_on_sigterm(node.stop)
        return node.spin()
    except Ros2Unavailable as error:
        print(f"autoscoop ros2 controller: error: {error}")
        return 2


def run_sim(args: argparse.Namespace) -> int:
    from autoscoop.deploy.ros2 import Ros2Unavailable  # noqa: PLC0415

    def run_node(bridge):
        _domain_checked()
        from autoscoop.deploy.ros2.sim_node import SimNode  # noqa: PLC0415

        node = SimNode(bridge, remaps=args.remap, log=_mcap_log(args.bag))
        _stop_on_sigterm(node.stop)
        return node.run(args.episodes, seed=args.seed, wait_for_controller_s=args.wait_s)

    return simulate(args, "ros2 sim", run_node, Ros2Unavailable)
