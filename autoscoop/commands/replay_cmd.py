"""``autoscoop replay LOG --policy P``: a robot's log through the controller, offline, before it drives.

Reads a ROS 1 ``.bag``, a ROS 2 bag folder or an MCAP file (``autoscoop ros2 controller|sim --bag``,
``ros2 bag record``, ``rosbag record``), feeds the recorded readings to the controller core at their
log times with their stamps (the watchdog judging them as on the robot), and writes, in --out:

- ``replay.csv``: per update, what was commanded (``sent_*``, empty where the log has no command) beside
  what the policy would have commanded, with the watchdog's verdict (``mode``, ``reason``);
- ``replay.png``: both against time, the spans where the controller stopped the robot marked.

Topic names, joint units and limits come from the robot file: --robot FILE, or else the one the log was
recorded with (``ros2 controller|sim --bag`` and ``ros sim --bag`` keep it, on ``~/robot``), or else the
built-in robot; names are relative to --namespace. Updates happen at the logged
commands' times (--schedule recorded, the default when the log has cmd_vel: on a log of
``ros2 controller --bag`` the same policy reproduces the commands sent) or at the controller's own
control periods and watchdog expiries (--schedule own).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from autoscoop.commands import check_output_dir, check_output_file, options, write_json
from autoscoop.commands.ros_cmd import build_controller


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("replay", help="replay a robot's log (ROS 1/2 bag, MCAP) through a policy, offline",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("log", type=Path, metavar="LOG", help="a ROS 1 .bag, a ROS 2 bag folder or an .mcap file")
    options.add_policy_option(parser, accepts="default (shipped), heuristic, a .onnx file or a policy file")
    options.add_robot_option(parser)
    options.retire_option(parser, "--config", "the robot file is --robot FILE (replay runs no simulation, so it "
                                              "takes no scene settings file)")
    options.retire_option(parser, "--robot-config", "the robot file is --robot FILE")
    options.add_set_option(parser, "scene/task config the policy was made for, e.g. --set pile.angle_deg=28")
    options.add_trust_option(parser)
    parser.add_argument("--namespace", default="/", help="the namespace the robot's topics lie in (default /)")
    parser.add_argument("--schedule", choices=("recorded", "own"), default=None,
                        help="update at the logged commands' times (default when the log has cmd_vel) or on the "
                             "controller's own control periods")
    options.add_out_option(parser, Path("out/replay"), "folder for replay.csv and replay.png")
    options.add_json_option(parser, "the summary (largest differences, verdicts)")
    options.add_allow_empty_option(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from autoscoop.deploy import replay  # noqa: PLC0415
    from autoscoop.deploy.controller import payload_inputs  # noqa: PLC0415

    check_output_dir(args.out, "--out")
    if args.json:
        check_output_file(args.json, "--json")
    from autoscoop.core.config import ScoopConfig, parse_set_args  # noqa: PLC0415

    ScoopConfig().with_overrides(parse_set_args(args.overrides))  # a bad --set is refused before the log is read
    robot_from = "--robot"
    if args.robot is None:
        robot_from, args = robot_of_the_log(args)
    core = build_controller(args)
    core.log = lambda level, text: None  # the verdicts are in the CSV, not one line per transition
    topics = core.config.topics
    needed = ("joint_states", "odom", "pile_range", *payload_inputs(core.config.payload), "scoop")
    try:
        log = replay.read_log(args.log, topics, needed, args.namespace)
    except ImportError as error:
        print(f"autoscoop replay: error: the ros2 extra is needed: pip install 'autoscoop[ros2]' ({error})")
        return 2
    has_commands = any(m.key == "cmd_vel" for m in log)
    schedule = args.schedule or ("recorded" if has_commands else "own")
    if schedule == "recorded" and not has_commands:
        raise replay.LogError(f"{args.log}: --schedule recorded needs the commands sent (topics.cmd_vel "
                              f"{topics.cmd_vel!r}), which the log does not have; use --schedule own")
    rows = replay.Replay(core).run(log, schedule)
    from autoscoop.core.safe_files import write_text_atomically  # noqa: PLC0415

    write_text_atomically(args.out / "replay.csv", replay.rows_as_csv(rows))
    biggest = replay.differences(rows)
    verdicts = {mode: sum(r.mode == mode for r in rows) for mode in ("running", "idle", "fault", "estop")}
    try:
        from autoscoop.report.replay_figure import plot_replay  # noqa: PLC0415

        channels = ("speed_mps", "lift_rad", "tilt_rad")
        plot_replay([r.time_s for r in rows], {c: [getattr(r, f"sent_{c}") for r in rows] for c in channels},
                    {c: [getattr(r, c) for r in rows] for c in channels}, [r.mode for r in rows],
                    args.out / "replay.png", title=f"{args.log.name}: {args.policy} ({schedule} schedule)")
        figure = str(args.out / "replay.png")
    except ImportError:
        figure = None
    print(f"{args.log}: {len(log)} messages, {len(rows)} updates ({schedule} schedule), policy {args.policy}, "
          f"robot file {robot_from}")
    for channel, value in biggest.items():
        print(f"  largest |sent - replayed| {channel}: " + ("n/a" if math.isnan(value) else f"{value:.3g}"))
    print("  verdicts: " + ", ".join(f"{mode} {count}" for mode, count in verdicts.items()))
    print(f"wrote {args.out / 'replay.csv'}" + (f" and {figure}" if figure else " (no figure: matplotlib missing)"))
    if args.json:
        write_json(args.json, {"log": str(args.log), "policy": args.policy, "schedule": schedule,
                               "messages": len(log), "updates": len(rows),
                               "max_difference": {k: (None if math.isnan(v) else v) for k, v in biggest.items()},
                               "verdicts": verdicts, "csv": str(args.out / "replay.csv"), "figure": figure,
                               "robot_file": robot_from})
    if not rows:
        return options.nothing_done("replay", f"no update: {args.log} has no commands and no inputs the "
                                              f"controller could act on", args.allow_empty)
    faults = [r for r in rows if r.mode == "fault"]
    if faults and all(r.mode in ("fault", "none") for r in rows):  # "none": a logged command before any update
        return options.nothing_done("replay", f"every update was a fault ({len(faults)} of {len(rows)}; the last: "
                                              f"{faults[-1].reason}); check the robot file's units and topics "
                                              f"(--robot FILE)", args.allow_empty)
    return 0


def robot_of_the_log(args: argparse.Namespace) -> tuple[str, argparse.Namespace]:
    """Without ``--robot``: the robot file the log keeps, written beside --out and named in ``args.robot``
    (the built-in robot where the log keeps none); where it came from, in words."""
    from autoscoop.core.safe_files import write_text_atomically  # noqa: PLC0415
    from autoscoop.deploy import replay  # noqa: PLC0415
    from autoscoop.deploy.robot_config import robot_from_yaml  # noqa: PLC0415

    try:
        found = replay.robot_file_in_log(args.log, args.namespace)
    except ImportError:
        return "built-in", args  # the read below says the extra is missing
    if found is None:
        return "built-in (the log keeps none)", args
    topic, text = found
    robot_from_yaml(text, f"{args.log} ({topic})")  # checked before it is written anywhere
    copy = args.out / "robot.yaml"
    write_text_atomically(copy, text)
    return f"{topic} of the log (copied to {copy})", argparse.Namespace(**{**vars(args), "robot": copy})
