"""``autoscoop teleop``: drive the loader yourself in MuJoCo's viewer and record each scoop.

Keys (also shown in the window): Up/Down drive faster forward/backward, Space stops, Page Up/Down
raise/lower the arm, Left/Right curl/tip the bucket, Enter ends the episode (and starts the next);
the numeric keypad works too (8/2, 5, 9/3, 4/6). Each finished episode is saved as an episode record
in OUT (default out/manual), which ``autoscoop compare`` picks up as the manual-control rows, and
``autoscoop report OUT`` draws. Needs a display.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from autoscoop.commands import config_from_args, options, records_dir_lock
from autoscoop.core.config import ScoopConfig

MANUAL_TIME_LIMIT_S = 20.0
"""Episode limit for people: the paper's manual cycles took 10 s on average, against 8 s for the controller's limit."""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("teleop", help="drive the loader with the keyboard and record the episodes",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    options.add_out_option(parser, Path("out/manual"), "folder for the records")
    options.add_episodes_option(parser, default=0, what="stop after this many episodes (0: until the window closes)", minimum=0)
    options.add_seed_option(parser)
    parser.add_argument("--speed", type=options.NumberIn(0.05, 4.0), default=1.0,
                        help="simulated seconds per wall second, in [0.05, 4] (0.5: half speed)")
    parser.add_argument("--time-limit", type=options.POSITIVE_SECONDS, default=MANUAL_TIME_LIMIT_S,
                        help=f"episode time limit, s (default {MANUAL_TIME_LIMIT_S:g}; the controllers get 8)")
    options.add_config_args(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from autoscoop.sim.glbackend import has_display  # noqa: PLC0415

    config = config_from_args(args).with_overrides({"env.max_episode_s": args.time_limit})  # usage errors first
    if not has_display(os.environ):
        raise SystemExit("autoscoop teleop needs a display (no DISPLAY or WAYLAND_DISPLAY is set)")
    with records_dir_lock(args.out, "--out"):  # one session at a time records into --out
        return _session(args, config)


def _session(args: argparse.Namespace, config: ScoopConfig) -> int:
    """Open the viewer, run the episodes the keyboard drives, save each finished one under ``args.out``."""
    import mujoco.viewer  # noqa: PLC0415

    from autoscoop.core.state import CommandLimits  # noqa: PLC0415
    from autoscoop.envs.scoop import make_scoop_env  # noqa: PLC0415
    from autoscoop.evaluation.recorder import EpisodeRecorder  # noqa: PLC0415
    from autoscoop.evaluation.teleop import SessionOptions, TeleopKeys, help_lines, run_session  # noqa: PLC0415

    env = EpisodeRecorder(make_scoop_env(config), {"policy": "manual", "source": "teleop"})
    keys = TeleopKeys(CommandLimits.for_robot(config.robot))
    print("autoscoop teleop: drive the loader into the pile, fill the bucket, lift it to the terminal point.")
    print("\n".join(f"  {key:<6} {doc}" for key, doc in help_lines()))
    sim = env.unwrapped.sim
    env.reset(seed=args.seed)  # builds the settled pile before the window opens
    with mujoco.viewer.launch_passive(sim.model, sim.data, key_callback=keys.press,
                                      show_left_ui=False, show_right_ui=False) as viewer:
        viewer.cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
        viewer.cam.fixedcamid = sim.model.camera("side").id
        saved = run_session(env, keys, viewer, SessionOptions(out_dir=args.out, seed=args.seed,
                                                              episodes=args.episodes, speed=args.speed))
    env.close()
    print(f"saved {len(saved)} manual episodes in {args.out}")
    return 0
