"""``autoscoop export``: write a trained policy's actor as ONNX (its scaling included) and check it.

The file runs with onnxruntime alone (``autoscoop ros controller --policy FILE.onnx`` needs no
torch). After writing it, the command compares it with the torch actor on random states over the
robot's workspace and prints the largest difference and the time of one inference step; it fails
when the difference exceeds 5e-5 (each runtime rounds in float32; see
``autoscoop.deploy.export.PARITY_TOLERANCE``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from autoscoop.commands import config_from_args, options, write_json
from autoscoop.core.policy import state_frame_of


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("export", help="export a policy's actor to ONNX (runs with onnxruntime alone)",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    options.add_policy_option(parser, accepts="default, a .safetensors file or a run directory")
    parser.add_argument("--onnx", type=onnx_path, required=True, metavar="OUT.onnx", help="the file to write")
    parser.add_argument("--check-states", type=options.NON_NEGATIVE, default=10_000, metavar="N",
                        help="random states for the parity check (default 10000; 0 skips it)")
    options.add_json_option(parser, "the parity check and timings")
    options.add_trust_option(parser)
    options.add_config_args(parser)
    parser.set_defaults(func=run)


def onnx_path(text: str) -> Path:
    """``type=`` of ``--onnx``: a path ending in ``.onnx``."""
    if not text.endswith(".onnx"):
        raise argparse.ArgumentTypeError(f"must name a .onnx file; got {text!r}")
    return Path(text)


def run(args: argparse.Namespace) -> int:
    from autoscoop.agents.loading import load_policy  # noqa: PLC0415

    config = config_from_args(args)
    policy = load_policy(args.policy, config, trust=args.trust)
    report = export_policy(policy, args.onnx, args.policy, args.check_states)
    if args.json and report is not None:
        write_json(args.json, {"onnx": str(args.onnx), "policy": args.policy, **report})
    if report is not None and not report["passed"]:
        print("parity check FAILED")
        return 1
    return 0


def export_policy(policy: object, onnx: Path, source: str, check_states: int = 10_000) -> dict | None:
    """Write a loaded policy's actor to ``onnx`` and, with ``check_states`` > 0, compare the file with the torch
    actor on that many random inputs; print what was done. Returns the parity report (``None`` unchecked)."""
    from autoscoop.deploy.export import check_parity, export_onnx, exportable_actor, random_actor_inputs  # noqa: PLC0415

    actor = exportable_actor(policy)
    path = export_onnx(actor, onnx, {"policy_name": getattr(policy, "name", source), "source_policy": source,
                                     "state_frame": state_frame_of(policy) or "chassis"})
    print(f"wrote {path} ({path.stat().st_size / 1024:.1f} KiB)")
    if check_states == 0:
        return None
    report = check_parity(actor, path, random_actor_inputs(check_states, getattr(actor, "history_steps", 1)))
    print(f"parity over {report['states']} random states: max |onnx - torch| = {report['max_abs_diff']:.2e} "
          f"(allowed {report['tolerance']:.0e}; float32 rounding: torch {report['torch_vs_float64']:.1e}, "
          f"onnxruntime {report['onnx_vs_float64']:.1e} from float64)")
    print(f"one inference step: onnxruntime {report['onnxruntime_step']['median_us']:.0f} us "
          f"(p99 {report['onnxruntime_step']['p99_us']:.0f}), torch {report['torch_step']['median_us']:.0f} us "
          f"(p99 {report['torch_step']['p99_us']:.0f}), one thread")
    return report
