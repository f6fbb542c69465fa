"""``autoscoop bench``: three measurements, one per mode.

  autoscoop bench               speed: physics steps/s, environment steps/s and real-time factor on one core
  autoscoop bench --n-envs N    scaling: aggregate environment steps/s of N environments stepped together (as
                                training builds them: subprocesses) against one, and the scaling ratio
  autoscoop bench payload       payload: error of the payload mass estimated from the joint torques (paper eq. 4, 8)

Each mode's own options are listed under its name below; --json, --config and --set apply to all three. An
option of another mode is refused rather than ignored.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from autoscoop.commands import check_output_file, config_from_args, options, write_json
from autoscoop.evaluation.bench import run_bench, run_vec_bench

MODE_OPTIONS = {"speed": ("episodes", "repeats"), "scaling": ("n_envs", "steps", "actions", "seed", "repeats"),
                "payload": ("episodes", "records", "calibration")}
"""each mode's own options (argparse names); --json, --config and --set apply to all three."""
MODE_COMMANDS = {"speed": "autoscoop bench", "scaling": "autoscoop bench --n-envs N", "payload": "autoscoop bench payload"}
OPTION_FLAGS = {"episodes": "--episodes", "repeats": "--repeats", "n_envs": "--n-envs", "steps": "--steps",
                "actions": "--actions", "seed": "--seed", "records": "--records", "calibration": "--calibration"}


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("bench", help="measure simulator speed, its scaling, or the payload estimate",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("target", nargs="?", choices=["payload"],
                        help="'payload': the payload mode (autoscoop.evaluation.payload_bench); without it, speed "
                             "or (with --n-envs) scaling")
    size = parser.add_argument_group("how much to measure (the modes that use each say so)")
    options.add_episodes_option(size, default=10, minimum=0, what="speed: scripted episodes per repeat, 1 or more; "
                                "payload: moving scoops after the static holds, 0 or more")
    size.add_argument("--repeats", type=options.POSITIVE, default=3, metavar="N",
                      help="speed and scaling: timed repeats, the median is reported (default 3)")
    scaling = parser.add_argument_group("scaling (autoscoop bench --n-envs N)")
    scaling.add_argument("--n-envs", type=options.POSITIVE, metavar="N",
                         help="measure aggregate env steps/s of N environments stepped together (SubprocVecEnv, as "
                              "`train --n-envs N`) against 1, and the ratio, instead of the one-core figures")
    scaling.add_argument("--steps", type=options.POSITIVE, default=2000, metavar="N",
                         help="steps each environment takes per repeat (default 2000)")
    scaling.add_argument("--actions", choices=["random", "fixed"], default="random",
                         help="uniform random actions (default) or the fixed middle action")
    options.add_seed_option(scaling, what="seed of the environments and actions")
    payload = parser.add_argument_group("payload (autoscoop bench payload)")
    payload.add_argument("--records", type=Path, metavar="DIR", help="write the static holds as records to this folder")
    payload.add_argument("--calibration", type=Path, metavar="FILE.yaml",
                         help="the estimators' calibration YAML (default nominal)")
    options.add_json_option(parser, "the results")
    options.add_config_args(parser)
    parser.set_defaults(func=run, option_defaults={name: parser.get_default(name) for name in OPTION_FLAGS})


def mode_of(args: argparse.Namespace) -> str:
    """The mode the arguments ask for: ``payload``, ``scaling`` (``--n-envs``) or ``speed``."""
    return "payload" if args.target == "payload" else "scaling" if args.n_envs is not None else "speed"


def refuse_other_modes_options(args: argparse.Namespace) -> None:
    """Refuse an option of another mode given a value of its own (it would be ignored without a word).

    Raises:
        ValueError: naming the option, the modes it belongs to and the mode asked for.
    """
    mode = mode_of(args)
    for name, flag in OPTION_FLAGS.items():
        if name not in MODE_OPTIONS[mode] and getattr(args, name) != args.option_defaults[name]:
            owners = " and ".join(f"{m} ({MODE_COMMANDS[m]})" for m, names in MODE_OPTIONS.items() if name in names)
            raise ValueError(f"{flag} is an option of {owners}, not of {mode} ({MODE_COMMANDS[mode]}); leave it out")


def run(args: argparse.Namespace) -> int:
    refuse_other_modes_options(args)
    if args.json:  # fail before the first measurement, not after the last
        check_output_file(args.json, "--json")
    if args.target == "payload":
        from autoscoop.commands.payload_cmd import run_payload_bench_cmd  # noqa: PLC0415

        return run_payload_bench_cmd(args)
    if args.n_envs is not None:
        return run_vec_bench_cmd(args)
    if args.episodes < 1:
        raise ValueError(f"--episodes must be 1 or more to measure speed; got {args.episodes}")
    result = run_bench(config_from_args(args), episodes=args.episodes, repeats=args.repeats)
    print(f"physics steps/s   {result['physics_steps_per_s']:10.0f}   (timestep {result['timestep_s']} s)")
    print(f"env steps/s       {result['env_steps_per_s']:10.1f}")
    repeats = ", ".join(f"{run['realtime_factor']:.1f}" for run in result["repeats"])
    print(f"real-time factor  {result['realtime_factor']:10.1f}   (median of {len(result['repeats'])}: "
          f"{repeats}; {result['cores']})")
    print(f"machine           {result['cpu']}, {result['cpu_count']} cores, MuJoCo {result['mujoco_version']}")
    if args.json:
        write_json(args.json, result)
        print(f"wrote {args.json}")
    return 0


def run_vec_bench_cmd(args: argparse.Namespace) -> int:
    """``bench --n-envs N``: the table of env steps/s with 1 and N environments and their ratio."""
    from autoscoop.training.factories import make_vec_env  # noqa: PLC0415 - SB3 only for this measurement

    result = run_vec_bench(make_vec_env, config_from_args(args), n_envs=args.n_envs, steps=args.steps,
                           repeats=args.repeats, seed=args.seed, actions=args.actions)
    n = result["n_envs"]
    print(f"env steps/s, 1 env     {result['env_steps_per_s_1']:10.1f}   (DummyVecEnv)")
    if n > 1:
        print(f"env steps/s, {n} envs    {result['env_steps_per_s_n']:10.1f}   ({result['vec_env']}; "
              f"{result['per_env_steps_per_s_n']:.1f} per env)")
    ratios = ", ".join(f"{run['scaling_ratio']:.2f}" for run in result["repeats"])
    print(f"scaling ratio          {result['scaling_ratio']:10.2f}   ({n} envs / 1; repeats: {ratios})")
    print(f"measured               {result['steps_per_env']} steps per env, {result['actions']} actions, "
          f"median of {len(result['repeats'])} repeats")
    print(f"machine                {result['cpu']}, {result['cpu_count']} cores "
          f"({result['usable_cores']} usable), MuJoCo {result['mujoco_version']}")
    if args.json:
        write_json(args.json, result)
        print(f"wrote {args.json}")
    return 0
