"""``autoscoop ros controller|sim``: the controller as a ROS 1 node, and the simulator behind the same topics.

Both need a running ``rosmaster`` (``ROS_MASTER_URI``) and ROS 1 from Debian's packages. Topic names
are relative: remap them with ``name:=new`` after the options, as with any ROS node, e.g.
``autoscoop ros controller --policy default joint_states:=/komodo/joint_states``.

The controller is not a substitute for the robot's hardware emergency stop.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

from autoscoop.commands import check_output_dir, check_output_file, config_from_args, options, write_json
from autoscoop.core.config import ConfigError, ScoopConfig, parse_set_args


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("ros", help="ROS 1 nodes: the controller on the robot, the simulator behind it",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    nodes = parser.add_subparsers(dest="node", metavar="NODE", required=True)

    controller = nodes.add_parser("controller", help="run a policy on the robot's topics, with watchdog and limits",
                                  description=_CONTROLLER_DOC, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_controller_options(controller)
    add_records_option(controller)
    controller.add_argument("remap", nargs="*", type=ros_remap, metavar="NAME:=NEW",
                            help="ROS remappings and private parameters")
    controller.set_defaults(func=run_controller)

    sim = nodes.add_parser("sim", help="the MuJoCo scene behind the robot's topics (like Gazebo)",
                           description=_SIM_DOC, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_sim_options(sim)
    sim.add_argument("--bag", type=bag_path, metavar="FILE",
                     help="record the node's topics to this ROS 1 bag (needs the ros2 extra's rosbags): every "
                          "sensor message and scoop flag as published, every command as it arrived")
    sim.add_argument("remap", nargs="*", type=ros_remap, metavar="NAME:=NEW", help="ROS remappings")
    sim.set_defaults(func=run_sim)


def add_controller_options(controller: argparse.ArgumentParser) -> None:
    """The options every controller node takes (``ros controller``, ``ros2 controller``), but where it records."""
    options.add_policy_option(controller, accepts="default (shipped), heuristic, a .onnx file (onnxruntime only) or a policy file")
    options.add_robot_option(controller, what=ROBOT_HELP)
    retire_robot_spellings(controller, scene=False)
    options.add_set_option(controller, "scene/task config the policy was made for, e.g. --set pile.angle_deg=28 (labels "
                               "the records; the heuristic aims at reward.terminal_*)")
    options.add_trust_option(controller)
    controller.add_argument("--check", action="store_true",
                            help="check the configuration and the policy, print them, and exit without ROS")


def add_sim_options(sim: argparse.ArgumentParser) -> None:
    """The options every simulator node takes (``ros sim``, ``ros2 sim``)."""
    options.add_episodes_option(sim, default=0, what="episodes to run, then exit (0: until stopped)", minimum=0)
    options.add_seed_option(sim, what="seed of the first episode (as in autoscoop eval)")
    options.add_json_option(sim, "the summary (as autoscoop eval does)")
    for flag, key, unit, what in LINK_OPTIONS:
        sim.add_argument(flag, type=options.NumberIn(0.0, None, unit), default=None, metavar=unit.upper().replace("/", "_").replace("*", "_"),
                         help=f"{what}, {unit}: the config key {key} (same as --set {key}=...; default 0)")
    options.add_robot_option(sim, what=ROBOT_HELP + "; the readings are published in its units (raw "
                             "potentiometer counts where it calibrates a joint): give the controller the same file")
    retire_robot_spellings(sim, scene=True)
    sim.add_argument("--label", help="policy name for the summary (default: the policy the controller announces)")
    sim.add_argument("--wait-s", type=options.POSITIVE_SECONDS, default=60.0,
                     help="give up when no controller appears within this long, s (default 60)")
    options.add_config_args(sim)
    options.add_allow_empty_option(sim)


ROBOT_HELP = (f"{options.ROBOT_FILE_HELP}; default: the built-in robot (joints lift and tilt read in radians, "
              f"the topics' default names)")
"""``--robot`` on the controller and simulator nodes: both default to the same built-in robot."""


def retire_robot_spellings(parser: argparse.ArgumentParser, scene: bool) -> None:
    """Refuse the robot file's old spellings: ``--robot-config`` and, on a node without a scene, ``--config``."""
    options.retire_option(parser, "--robot-config", "the robot file is --robot FILE")
    if not scene:
        options.retire_option(parser, "--config", "the robot file is --robot FILE (this command runs no "
                                                  "simulation, so it takes no scene settings file)")


def add_records_option(controller: argparse.ArgumentParser) -> None:
    """``--records DIR`` on a controller node (``--record`` refused, naming it and ``--bag``)."""
    controller.add_argument("--records", type=Path, metavar="DIR", help="write one episode record per scoop here")
    options.retire_option(controller, "--record", "episode records are --records DIR (a recorded bag, where the "
                                                  "node writes one, is --bag FILE)")


LINK_OPTIONS = (
    ("--delay-s", "sensor.delay_s", "s", "delay of every sensor message"),
    ("--joint-noise-rad", "sensor.joint_noise_rad", "rad", "noise (std) on the joint angles and the IMU's pitch"),
    ("--speed-noise-mps", "sensor.speed_noise_mps", "m/s", "noise (std) on the odometry speed"),
    ("--range-noise-m", "sensor.range_noise_m", "m", "noise (std) on the range to the pile"),
    ("--torque-noise-nm", "sensor.torque_noise_nm", "N*m", "noise (std) on each joint torque (bucket and lift)"),
)
"""``ros sim``'s link options: (flag, the config key it sets, unit, meaning)."""


_CONTROLLER_DOC = """Run a policy on the robot through ROS 1.

Subscribes: joint_states (sensor_msgs/JointState: lift, tilt), odom (nav_msgs/Odometry), pile_range
(sensor_msgs/Range), bucket_torque (the tilt joint's torque) and lift_torque (std_msgs/Float64, N*m: the
payload mass by eq. 8;
payload.method: eq4 needs bucket_torque only, payload.source: topic reads payload_mass in kg instead),
estop (std_msgs/Bool), scoop (std_msgs/Bool: true starts a scoop, false ends it). Publishes: cmd_vel
(geometry_msgs/Twist), lift_controller/command and tilt_controller/command (std_msgs/Float64, rad),
~status (std_msgs/String).

Every command is clamped to the configured limits. Any input older than control.input_timeout_s, or
not finite, or out of range -> zero velocity and the arm held, until the inputs are healthy again;
estop true -> the same until estop false. Not a substitute for the hardware emergency stop.
"""

_SIM_DOC = """The simulator as a ROS 1 node: publishes joint_states, odom, pile_range, bucket_torque,
lift_torque and payload_mass (with noise and delay as configured) in real time, obeys cmd_vel and the joint commands, and starts each
episode on the scoop topic. --episodes N --json OUT writes the summary of `autoscoop eval`.
"""


def ros_remap(text: str) -> str:
    """``type=`` of the arguments after the options: ROS remappings ``NAME:=NEW`` only."""
    if ":=" not in text:
        raise argparse.ArgumentTypeError(f"unexpected {text!r}: only ROS remappings NAME:=NEW may follow the options")
    return text


def build_controller(args: argparse.Namespace, record_dir: Path | None = None):
    """The checked controller core from the command line (no ROS needed); its episode records go to
    ``record_dir``."""
    from autoscoop.agents.loading import load_policy  # noqa: PLC0415
    from autoscoop.deploy.controller import ControllerCore  # noqa: PLC0415
    from autoscoop.deploy.robot_config import load_robot_config  # noqa: PLC0415

    robot = load_robot_config(args.robot)
    task = ScoopConfig().with_overrides({**parse_set_args(args.overrides),
                                         "env.control_period_s": robot.control.control_period_s})
    policy = load_policy(args.policy, task, trust=args.trust)
    return ControllerCore(robot, policy, task, record_dir=record_dir, policy_name=args.policy)


def checked_controller(args: argparse.Namespace, record_dir: Path | None):
    """:func:`build_controller`, a ConfigError saying the controller did not start; with ``--check``, the
    configuration printed and ``None`` (the command then exits 0)."""
    try:
        core = build_controller(args, record_dir)
    except ConfigError as error:
        raise ConfigError(f"controller not started: {error}") from None
    if args.check:
        print(core.config.describe())
        print(f"policy: {core.policy_name} ({type(core.policy).__name__}); configuration OK")
        return None
    return core


def run_controller(args: argparse.Namespace) -> int:
    if args.records:
        check_output_dir(args.records, "--records")
    core = checked_controller(args, args.records)
    if core is None:
        return 0
    from autoscoop.deploy.ros1 import RosUnavailable  # noqa: PLC0415

    try:
        from autoscoop.deploy.ros1.controller_node import ControllerNode  # noqa: PLC0415

        return ControllerNode(core).spin()
    except RosUnavailable as error:
        print(f"autoscoop ros controller: error: {error}")
        return 2


def bag_path(text: str) -> Path:
    """``type=`` of ``--bag``: a path ending in ``.bag``."""
    if not text.endswith(".bag"):
        raise argparse.ArgumentTypeError(f"{text!r}: a ROS 1 bag's name ends in .bag")
    return Path(text)


def run_sim(args: argparse.Namespace) -> int:
    if args.bag:
        check_output_file(args.bag, "--bag")

    def run_node(bridge):
        from autoscoop.deploy.ros1.sim_node import SimNode  # noqa: PLC0415

        log = None
        if args.bag:
            from autoscoop.deploy.ros1.bag_log import Ros1BagLog  # noqa: PLC0415

            log = Ros1BagLog(args.bag)
        return SimNode(bridge, log=log).run(args.episodes, seed=args.seed, wait_for_controller_s=args.wait_s)

    from autoscoop.deploy.ros1 import RosUnavailable  # noqa: PLC0415

    return simulate(args, "ros sim", run_node, RosUnavailable)


def simulate(args: argparse.Namespace, command: str, run_node: Callable[[Any], tuple[list, Any]],
             unavailable: type[Exception]) -> int:
    """``ros sim`` and ``ros2 sim``: the simulator from the options, ``run_node(bridge)`` (the episodes over a
    middleware: outcomes and a SimRunStats), then the summary of ``autoscoop eval`` printed and written.

    Args:
        args: the sim's options (:func:`register`).
        command: the command's name, for its messages.
        run_node: runs the episodes of a :class:`~autoscoop.deploy.sim_bridge.SimBridge`.
        unavailable: the error the middleware raises when it is not installed (exit 2, its message).
    """
    from autoscoop.deploy.robot_config import load_robot_config  # noqa: PLC0415
    from autoscoop.deploy.sim_bridge import SimBridge  # noqa: PLC0415
    from autoscoop.evaluation.evaluate import format_table, summarize  # noqa: PLC0415

    if args.json:
        check_output_file(args.json, "--json")  # before the episodes, not after them
    config = config_from_args(args)
    link = {key: getattr(args, flag.lstrip("-").replace("-", "_")) for flag, key, _, _ in LINK_OPTIONS}
    try:  # the link options are the environment's sensor keys: one range check, errors naming the key
        config = config.with_overrides({key: value for key, value in link.items() if value is not None})
    except ConfigError as error:
        raise ConfigError(f"{command}: {error}") from None
    bridge = SimBridge(config, robot=load_robot_config(args.robot), seed=args.seed)
    try:
        results, stats = run_node(bridge)
        label = args.label or stats.controller_policy or "ros controller"
    except unavailable as error:
        print(f"autoscoop {command}: error: {error}")
        return 2
    except TimeoutError as error:
        print(f"autoscoop {command}: error: {error}")
        return 1
    finally:
        bridge.close()
    if not results:
        return options.nothing_done(command, "no episode finished" + (
            "" if stats.commands_received else ": no command arrived from the controller"), args.allow_empty)
    summary = summarize(results, config, label)
    summary["ros"] = {"sensor_period_s": bridge.sensor_period_s, "delay_s": config.sensor.delay_s,
                      "noise": vars(bridge.noise), **stats.as_dict()}
    print(format_table(summary))
    print(f"real-time factor {summary['ros']['real_time_factor']:.2f}, late steps {stats.late_steps}")
    if args.json:
        write_json(args.json, summary)
        print(f"wrote {args.json}")
    why = nothing_achieved(results, stats.commands_received)
    return options.nothing_done(command, why, args.allow_empty) if why else 0


def nothing_achieved(results: list, commands_received: int) -> str | None:
    """Why a simulator's run achieved nothing, or ``None`` when a scoop reached the terminal point.

    Args:
        results: the episodes' outcomes (:class:`~autoscoop.envs.outcome.EpisodeOutcome`).
        commands_received: the commands that arrived from the controller over the whole run.
    """
    if commands_received == 0:
        return (f"no command arrived from the controller in {len(results)} episode(s): check that it runs in "
                f"the same namespace and domain and subscribes to the simulator's topics")
    if not any(result.reached for result in results):
        fill = sum(result.fill_factor for result in results) / len(results)
        return (f"no scoop reached the terminal point in {len(results)} episode(s) (mean fill {fill:.3f}); the "
                f"controller's status topic says why it stopped, e.g. a reading it judged a fault")
    return None

