"""``autoscoop sweep``: train trials over a search space on Ray Tune, rank them, export the best policy.

Each trial is an ordinary ``autoscoop train`` run (``OUT/runs/TRIAL_ID``, loadable by ``eval --policy``) that
reports its periodic evaluations to Tune. Ray starts embedded on this machine, or the trials run on the
Ray cluster at ``--address``. ``--resume DIR`` continues the interrupted sweep in DIR (its driver killed,
kill -9 included) without training its finished trials again. At the end: ``OUT/sweep.csv``, ``OUT/report.md``
(trials ranked by score), ``OUT/sweep.png`` (score against each swept setting) and the best trial's actor
as ``OUT/best.safetensors`` (+ ``.json``). Needs the ``sweep`` extra (``pip install 'autoscoop[sweep]'``);
see docs/sweep.md.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import TYPE_CHECKING

from autoscoop.commands import check_output_dir, check_output_file, options, write_json
from autoscoop.core.config import read_yaml_file
from autoscoop.core.version import __version__

if TYPE_CHECKING:
    from autoscoop.training.sweep import SweepResult
    from autoscoop.training.sweep_space import SweepSpace

OUTPUTS = ("sweep.csv", "report.md", "sweep.png", "best.safetensors", "best.json")
"""what the sweep writes into ``--out`` at the end."""


RESUME_WITHOUT_FOLDER = True
"""``--resume`` given no folder (not a string: argparse would parse one as a path): the old spelling,
``--out DIR --resume``, refused naming the new one."""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("sweep", help="train trials over a search space on Ray Tune and rank them",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--space", type=Path, metavar="SPACE.yaml",
                        help="the search space: config keys (--set keys), algorithm keys (--hyper keys), seeds "
                             "(docs/sweep.example.yaml); with --resume optional, and then it must be the recorded one")
    parser.add_argument("--trials", type=options.POSITIVE, metavar="N",
                        help="trials in all: a multiple of the space's grid (seeds x grid lists)")
    options.add_episodes_option(parser, default=None, what="training episodes per trial")
    options.add_out_option(parser, None, "the new sweep's folder (trials' run directories, Tune's state, the "
                                 "report); on a cluster it must be shared storage, at the same path on every node")
    parser.add_argument("--address", metavar="HOST:PORT",
                        help="run on this Ray cluster (`ray start --head` prints it); default: Ray embedded here")
    parser.add_argument("--resume", type=Path, nargs="?", const=RESUME_WITHOUT_FOLDER, metavar="RUN_DIR",
                        help="continue the interrupted sweep in this folder (the --out it started with), as train "
                             "--resume does a run; finished trials are not trained again")
    options.add_json_option(parser, "the table and the sweep's facts, too,")
    parser.add_argument("--num-cpus", type=options.POSITIVE, metavar="N",
                        help="CPUs embedded Ray may use, one per trial (default: all of this machine's)")
    parser.add_argument("--max-concurrent", type=options.POSITIVE, metavar="N",
                        help="most trials at once (default: as many as the CPUs allow)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.space:  # read within bounds before torch is imported: a hostile file fails in a fraction of a second
        read_yaml_file(args.space, "space file")
    # torch (through the algorithms' settings) is slow to import: only when the command runs
    from autoscoop.training.sweep import (  # noqa: PLC0415
        SweepArgs,
        check_address,
        check_resume_matches,
        read_plan,
        require_ray,
        resume_sweep,
        start_sweep,
    )
    from autoscoop.training.sweep_space import check_episodes, load_space, plan_trials, space_from_dict  # noqa: PLC0415

    _check_cluster_options(args)
    _resolve_folder(args)
    if args.resume:
        plan = read_plan(args.out)
        given = load_space(args.space) if args.space else None
        check_resume_matches(plan, given, args.trials, args.episodes)
        space, trials, episodes = space_from_dict(plan["space"]), plan["trials"], plan["episodes"]
        space_file = plan.get("space_file", "")
    else:
        missing = [option for option, value in (("--space", args.space), ("--trials", args.trials),
                                                ("--episodes", args.episodes), ("--out", args.out)) if value is None]
        if missing:
            raise ValueError(f"{', '.join(missing)} must be given to start a sweep (--resume continues one)")
        space, trials, episodes, space_file = load_space(args.space), args.trials, args.episodes, str(args.space)
        plan_trials(space, trials)
        check_episodes(space, episodes)
    check_output_dir(args.out, "--out")  # fail before Ray starts, not after the last trial
    for name in OUTPUTS:
        check_output_file(args.out / name, "--out")
    if args.json:
        check_output_file(args.json, "--json")
    require_ray()
    if args.address:
        check_address(args.address)
    sweep_args = SweepArgs(space=space, trials=trials, episodes=episodes, out=args.out, address=args.address,
                           num_cpus=args.num_cpus, max_concurrent=args.max_concurrent, space_file=space_file,
                           command=_command_line(args))
    where = args.address or f"embedded Ray ({args.num_cpus or os.cpu_count()} CPUs)"
    print(f"{'resuming' if args.resume else 'starting'} a sweep of {trials} trials x {episodes} episodes "
          f"({space.algo}, {space.recipe} recipe) on {where}, into {args.out}", flush=True)
    result = resume_sweep(sweep_args) if args.resume else start_sweep(sweep_args)
    return _write_outputs(args, result, space)


def _resolve_folder(args: argparse.Namespace) -> None:
    """``--resume DIR`` names the sweep's folder: ``args.out`` becomes it (a different ``--out`` is refused)."""
    if args.resume is RESUME_WITHOUT_FOLDER:
        shown = args.out or "DIR"
        raise ValueError(f"--resume takes the sweep's folder: --resume {shown} (not --out {shown} --resume)")
    if args.resume is None:
        return
    if args.out is not None and args.out.resolve() != args.resume.resolve():
        raise ValueError(f"--out {args.out} and --resume {args.resume}: a resumed sweep stays in its folder; "
                         f"give --resume {args.resume} alone")
    args.out = args.resume


def _check_cluster_options(args: argparse.Namespace) -> None:
    if args.address and args.num_cpus is not None:
        raise ValueError("--num-cpus is for embedded Ray only; a cluster's nodes give their CPUs to `ray start`")


def _command_line(args: argparse.Namespace) -> str:
    parts = ["autoscoop sweep", f"--resume {args.resume}" if args.resume else f"--out {args.out}"]
    parts += [f"--space {args.space}"] if args.space else []
    return " ".join(parts)


def _write_outputs(args: argparse.Namespace, result: SweepResult, space: SweepSpace) -> int:
    """Export the best policy, write the table, report, figure and ``--json``; 1 if a trial failed, else 0."""
    from autoscoop.report.sweep import sweep_data, sweep_table, write_sweep_report  # noqa: PLC0415 - torch
    from autoscoop.training.sweep import short  # noqa: PLC0415 - torch
    from autoscoop.training.sweep_results import export_best, ranked  # noqa: PLC0415 - torch

    out = args.out.resolve()
    rows = result.rows
    scored = [row for row in ranked(rows) if row.score == row.score]  # NaN: no evaluation
    best = scored[0] if scored else None
    sweep_info = {"trials": result.plan["trials"], "episodes": result.plan["episodes"],
                  "space_file": result.plan.get("space_file", "")}
    best_path = export_best(best, out / "best.safetensors", sweep_info) if best else None
    sessions = result.plan["sessions"]
    intro = (f"`{result.plan.get('space_file') or 'the recorded space'}`: {result.plan['trials']} trials x "
             f"{result.plan['episodes']} episodes of `{space.algo}` (`{space.recipe}` recipe), on {result.ray}. "
             f"Wall time {result.wall_s:.0f} s in this driver run; {result.total_wall_s:.0f} s over "
             f"{len(sessions)} driver run(s) (a killed one counted to its last trial event). Each trial is an "
             "`autoscoop train` run in `runs/TRIAL_ID/` (`autoscoop eval --policy DIR/runs/TRIAL_ID`).")
    if best is None:
        outro = "No trial has an evaluation yet: there is no best policy."
    else:
        shown = ", ".join([*(f"`{k}` = {short(v)}" for k, v in best.settings.items()), f"seed {best.seed}"])
        outro = (f"Best: trial `{best.trial_id}` ({shown}), score {best.score:.3f}. " +
                 (f"Its policy is `{best_path.name}` (+ `best.json`): `autoscoop eval --policy {args.out / best_path.name}`."
                  if best_path else "Its policy has no safe actor file (PPO): use its run directory's `policy.zip`."))
    files = write_sweep_report(rows, space, out, title=f"Sweep: {Path(result.plan.get('space_file') or 'space').name}",
                               intro=intro, outro=outro)
    if args.json:
        write_json(args.json, sweep_data(rows, space, {
            "out": str(out), "space_file": result.plan.get("space_file", ""), "trials": result.plan["trials"],
            "episodes": result.plan["episodes"], "ray": result.ray, "cpu_count": os.cpu_count(),
            "wall_time_s": round(result.wall_s, 1), "total_wall_time_s": round(result.total_wall_s, 1),
            "driver_runs": sessions, "best_policy": str(best_path) if best_path else None,
            "errors": result.errors, "autoscoop_version": __version__}))
    print(sweep_table(rows, list(space.swept()), out))
    print(outro)
    for line in result.errors:
        print(f"failed: {line}")
    written = [files.table, files.markdown, files.figure, *([best_path] if best_path else []),
               *([args.json] if args.json else [])]
    print(f"wrote {', '.join(str(path) for path in written)}")
    return 1 if result.errors else 0
