"""``autoscoop compare``: the learned controller, the scripted baseline and manual episodes on three piles.

Evaluates each controller for N episodes (seeds SEED, SEED+1, ...) on each pile angle (the paper's
robot experiments used three; 25°, 32° and 40° by default), saving every episode's record under
OUT/records/CONTROLLER/ANGLEdeg/. Manual episodes recorded with ``autoscoop teleop`` join the
report as they are (found in --manual folders). OUT/report.md holds the paper's Table 2 in our data
(mass, particles, fill factor, cycle time, success, spillage: mean ± std) and the tip trajectories
per pile angle (Fig. 13); ``autoscoop report`` redraws it from the records. Every number in it is
the one ``autoscoop eval --policy P --set pile.angle_deg=A --episodes N --seed SEED`` prints.
"""

from __future__ import annotations

import argparse
import shlex
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
from autoscoop.core.config import PILE_ANGLE_RANGE_DEG, ScoopConfig
from autoscoop.evaluation.evaluate import evaluate, format_table, summarize

PILE_ANGLES_DEG = (25.0, 32.0, 40.0)
"""The three public pile angles compared (mean inclination of the pile's face)."""
DEFAULT_MANUAL = Path("out/manual")


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("compare", help="compare controllers on three pile angles (Table 2, Fig. 13)",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policies", nargs="+", default=["default", "heuristic"],
                        help="controllers to evaluate (default: default heuristic)")
    parser.add_argument("--angles", nargs="+", type=options.NumberIn(*PILE_ANGLE_RANGE_DEG, "deg"), default=list(PILE_ANGLES_DEG),
                        help="pile angles, degrees (default 25 32 40)")
    options.add_episodes_option(parser, default=100, what="episodes per controller and pile")
    options.add_seed_option(parser)
    parser.add_argument("--manual", nargs="*", type=Path, default=None,
                        help=f"folders or files of manual episode records (default {DEFAULT_MANUAL} if it exists)")
    options.add_out_option(parser, Path("out/compare"))
    options.add_overwrite_option(parser, "replace the episode records an earlier compare left under --out "
                                         "(refused otherwise)")
    options.add_trust_option(parser)
    options.add_config_args(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    base = config_from_args(args)
    check_outputs(args.out, [records_folder(args.out, spec, angle) for spec in args.policies for angle in args.angles],
                  args.overwrite)
    for spec in args.policies:  # a bad --policies entry fails now, not after the others' episodes
        load_policy(spec, base, trust=args.trust)
    with records_dir_lock(args.out, "--out"):  # one compare at a time writes --out's records
        return _compare(args, base, started)


def _compare(args: argparse.Namespace, base: ScoopConfig, started: float) -> int:
    from autoscoop.report.data import find_record_files, load_episodes  # noqa: PLC0415 - matplotlib when needed
    from autoscoop.report.markdown import write_report  # noqa: PLC0415

    manual = args.manual if args.manual is not None else ([DEFAULT_MANUAL] if DEFAULT_MANUAL.is_dir() else [])
    record_dirs: list[Path] = []
    summaries = []
    evaluated = []
    for spec in args.policies:
        for angle in args.angles:
            config = base.with_overrides({"pile.angle_deg": angle})
            policy = load_policy(spec, config, trust=args.trust)
            folder = records_folder(args.out, spec, angle)
            for old in folder.glob("episode_*.npz"):  # --overwrite (checked): a previous run's would join the table
                old.unlink()
            results = evaluate(policy, config, args.episodes, seed=args.seed, records_dir=folder,
                               records_meta={"policy": spec, "source": "compare"})
            summary = summarize(results, config, spec)
            print(format_table(summary, definitions=False) + "\n")  # report.md defines the terms
            summaries.append({k: v for k, v in summary.items() if k != "config"})
            record_dirs.append(folder)
        evaluated.append(spec)

    manual_files = find_record_files(manual) if manual else []
    episodes = load_episodes([*record_dirs, *manual_files])
    redraw = [args.out / "records", *manual]
    intro = (f"Controllers {', '.join(evaluated)}: {args.episodes} episodes each (seeds {args.seed}–"
             f"{args.seed + args.episodes - 1}) on each pile angle ({', '.join(f'{a:g}°' for a in args.angles)}); "
             + (f"{len(manual_files)} manual episodes recorded with `autoscoop teleop`." if manual_files
                else "no manual episodes (record some with `autoscoop teleop`)."))
    files = write_report(episodes, args.out, title="autoscoop: controllers compared", intro=intro,
                         command="autoscoop report " + " ".join(shlex.quote(str(p)) for p in redraw)
                                 + f" --out {args.out}")
    write_json(args.out / "summary.json", {"evaluated": summaries, "manual_records": [str(p) for p in manual_files]})
    print("\n".join(f"wrote {path}" for path in [files.markdown, *files.figures, args.out / "summary.json"]))
    print(f"compare took {time.perf_counter() - started:.0f} s")
    return 0


def records_folder(out: Path, spec: str, angle: float) -> Path:
    """Where ``compare`` saves the records of controller ``spec`` on the pile of ``angle`` degrees."""
    from autoscoop.report.markdown import slug  # noqa: PLC0415 - matplotlib when needed

    return out / "records" / slug(spec) / f"{angle:g}deg"


def check_outputs(out: Path, record_dirs: list[Path], overwrite: bool = False) -> None:
    """Fail before the first episode (ValueError naming the path) if ``--out`` or a file or folder under it
    could not be written: the report, ``summary.json``, the records folders; or, without ``overwrite``, if a
    records folder already holds an earlier run's episodes."""
    check_output_dir(out, "--out")
    for name in ("report.md", "summary.json"):
        check_output_file(out / name, "--out")
    for folder in record_dirs:
        check_output_dir(folder, "--out")
        if not overwrite and any(folder.glob("episode_*.npz")):
            raise ValueError(f"--out {out}: {folder} already holds an earlier compare's episode records; "
                             "pass --overwrite to replace them, or use another --out")
