"""``autoscoop demo``: watch the loader scoop the default pile; print its metrics, write a video and figures.

Runs the controller for a few episodes (records in OUT/records), prints the metrics table, films the
first episode off-screen (OUT/scoop.mp4 and OUT/scoop.gif) and draws the paper's Fig. 9 and Fig. 11
from the records (OUT/report.md with its PNGs). ``autoscoop report OUT/records --out OUT`` redraws
the figures without simulating.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from autoscoop.agents.loading import load_policy
from autoscoop.commands import (
    check_output_dir,
    check_output_file,
    config_from_args,
    options,
    records_dir_lock,
    write_json,
)
from autoscoop.core.config import ScoopConfig
from autoscoop.core.policy import Policy
from autoscoop.evaluation.evaluate import evaluate, format_table, summarize

DEFAULT_OUT = Path("out/demo")


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("demo", help="watch the shipped controller scoop: metrics, video, figures",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    options.add_policy_option(parser)
    options.add_episodes_option(parser, default=10, what="episodes for the metrics table")
    options.add_seed_option(parser, what="seed of the first episode, the one filmed")
    options.add_out_option(parser, DEFAULT_OUT)
    parser.add_argument("--fps", type=options.NumberIn(8.0, 1000.0), default=16.0,
                        help="video frames per simulated second, 8 or more (default 16)")
    parser.add_argument("--no-video", action="store_true", help="skip the video (figures and table only)")
    options.add_config_args(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    config = config_from_args(args)
    out: Path = args.out
    records = out / "records"
    check_outputs(out, records, video=not args.no_video)  # before the first episode, not after the last
    policy = load_policy(args.policy, config)  # a policy that cannot load leaves no folder behind
    with records_dir_lock(records, "--out"):  # one demo at a time clears, fills and reports OUT/records
        return _demo(args, config, policy, out, records, started)


def _demo(args: argparse.Namespace, config: ScoopConfig, policy: Policy, out: Path, records: Path,
          started: float) -> int:
    """Record, tabulate, film and report the demo's episodes (under ``records``' lock)."""
    from autoscoop.report.data import load_episodes  # noqa: PLC0415 - matplotlib only when needed
    from autoscoop.report.markdown import write_report  # noqa: PLC0415

    name = args.policy
    for old in records.glob("episode_*.npz"):  # a previous demo's episodes would join this report
        old.unlink()

    results = evaluate(policy, config, args.episodes, seed=args.seed, records_dir=records,
                       records_meta={"policy": name, "source": "demo"})
    summary = summarize(results, config, name)
    print(format_table(summary))
    write_json(out / "summary.json", summary)
    written = [out / "summary.json"]

    if not args.no_video:
        written += _film(policy, config, args.seed, args.fps, out, results[0])

    report = write_report(
        load_episodes([records]), out, title=f"autoscoop demo: {name} on the {config.pile.angle_deg:g}° pile",
        intro=f"{args.episodes} episodes from seed {args.seed}; the video shows seed {args.seed}.\n\n"
              + ("![the loader scooping](scoop.gif)\n" if not args.no_video else ""),
        command=f"autoscoop report {records} --out {out}")
    written += [report.markdown, *report.figures]
    print("\n".join(f"wrote {path}" for path in written))
    print(f"wrote {len(results)} episode records to {records}")
    print(f"demo took {time.perf_counter() - started:.0f} s")
    return 0


def check_outputs(out: Path, records: Path, video: bool) -> None:
    """Fail (ValueError naming the path) if ``--out`` or what the demo writes under it could not be written."""
    check_output_dir(out, "--out")
    check_output_dir(records, "--out")
    for name in ("summary.json", "report.md", *(("scoop.mp4", "scoop.gif") if video else ())):
        check_output_file(out / name, "--out")


def _film(policy: Policy, config: ScoopConfig, seed: int, fps: float, out: Path, evaluated) -> list[Path]:
    from autoscoop.evaluation.render import render_episode  # noqa: PLC0415 - needs OpenGL
    from autoscoop.report.video import write_gif, write_mp4  # noqa: PLC0415

    capture, _, result = render_episode(policy, config, seed, fps=fps)
    if (result.particles, result.steps, result.success) != (evaluated.particles, evaluated.steps, evaluated.success):
        print(f"warning: the filmed episode (seed {seed}) differs from the evaluated one: {result} vs {evaluated}")
    mp4 = write_mp4(capture.frames, out / "scoop.mp4", fps=capture.fps)
    gif = write_gif(capture.frames, out / "scoop.gif", fps=capture.fps)
    simulated = capture.times_s[-1] if capture.times_s else 0.0
    print(f"video: {len(capture.frames)} frames over {simulated:.2f} simulated s ({capture.fps:g} frames/s)")
    return [mp4, gif]
