"""``autoscoop bench``: physics steps/s, environment steps/s and real-time factor on one core.

``autoscoop bench payload``: error of the payload mass estimated from the joint torques (paper eq. 4, 8).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from autoscoop.commands import add_config_args, check_output_file, config_from_args, write_json
from autoscoop.evaluation.bench import run_bench


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("bench", help="measure simulator speed on one core", description=__doc__)
    parser.add_argument("target", nargs="?", choices=["payload"],
                        help="'payload': error of the torque mass estimate (autoscoop.evaluation.payload_bench) instead of speed")
    parser.add_argument("--episodes", type=int, default=10, help="scripted episodes per repeat (payload: moving scoops)")
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats (the median is reported)")
    parser.add_argument("--json", type=Path, help="write the results to this JSON file")
    parser.add_argument("--records", type=Path, help="payload: write the static holds as records to this folder")
    parser.add_argument("--calibration", type=Path, help="payload: the estimators' calibration YAML (default nominal)")
    add_config_args(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.json:  # fail before the first measurement, not after the last
        check_output_file(args.json, "--json")
    if args.target == "payload":
        from autoscoop.commands.payload_cmd import run_payload_bench_cmd  # noqa: PLC0415

        return run_payload_bench_cmd(args)
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
