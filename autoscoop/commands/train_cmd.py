"""``autoscoop train``: train a scooping controller (DDPG, the paper's, or TD3, SAC, PPO) from a recipe into a
run directory; plain ``autoscoop train`` runs the shipped policy's recipe, ``--recipe paper`` the paper's."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING

from autoscoop.commands import options
from autoscoop.core.config import overrides_from_yaml, parse_set_args, read_yaml_file
from autoscoop.envs import worlds_help
from autoscoop.training.recipes import DEFAULT_EPISODES, RECIPES, SHIPPED_RECIPE, algorithm_names, recipes_help

if TYPE_CHECKING:
    from autoscoop.evaluation.selection import Ranked
    from autoscoop.training.settings import SelectionSettings

DEFAULTS = {"algo": "ddpg", "recipe": SHIPPED_RECIPE, "seed": 0, "n_envs": 1, "checkpoint_every": 50, "eval_every": 50, "eval_episodes": 10}
"""a new run's settings where the options are not given (episodes: :data:`DEFAULT_EPISODES`). The options
default to ``None`` so that ``--resume`` can tell what was given."""
RECORDED = {"algo": "--algo", "recipe": "--recipe", "seed": "--seed", "n_envs": "--n-envs", "checkpoint_every": "--checkpoint-every",
            "eval_every": "--eval-every", "eval_episodes": "--eval-episodes", "demo_episodes": "--demo-episodes"}
"""options whose value a run records in ``run.json`` (key: option): ``--resume`` takes them only with that value."""
NOT_WITH_RESUME = {"out": "--out", "init": "--init", "config": "--config", "overrides": "--set", "hyper": "--hyper"}
"""options ``--resume`` refuses (argparse name: option): the run directory is ``--resume``'s, and the run keeps
the settings in its ``config.yaml`` and ``hyperparams.yaml``."""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("train", help="train a controller", description=__doc__,
                                   epilog=worlds_help("the recipe's (its env keys, then its curriculum's)"))
    parser.add_argument("--algo", choices=algorithm_names(),
                        help="algorithm (default ddpg, the paper's); settings in autoscoop/training/hyperparams/ALGO.yaml")
    parser.add_argument("--recipe", choices=RECIPES,
                        help=f"{recipes_help()} (autoscoop/training/recipes/NAME.yaml, laid over the algorithm's "
                             "YAML)".replace("%", "%%"))
    options.add_episodes_option(parser, default=None, what=f"training episodes (default: the recipe's, else "
                        f"{DEFAULT_EPISODES} as in the paper; not with --resume: a resumed run keeps its recorded count)")
    options.add_seed_option(parser, default=None, what="random seed", shown_default=DEFAULTS["seed"])
    parser.add_argument("--n-envs", type=options.POSITIVE, metavar="N", help="parallel simulators in subprocesses (default 1)")
    parser.add_argument("--checkpoint-every", type=options.POSITIVE, metavar="N", help="episodes between checkpoints (default 50)")
    parser.add_argument("--eval-every", type=options.NON_NEGATIVE, metavar="N",
                        help="episodes between evaluations of the deterministic policy; the best is kept "
                             "(0: keep the last; default 50)")
    parser.add_argument("--eval-episodes", type=options.POSITIVE, metavar="N", help="episodes per evaluation (default 10)")
    options.add_out_option(parser, None, "run directory (default runs/ALGO-sSEED-TIME)")
    parser.add_argument("--resume", type=Path, metavar="RUN_DIR",
                        help="continue an interrupted run with its recorded settings (--config, --set, --hyper, "
                             "--init, --out and settings other than the recorded ones are refused)")
    parser.add_argument("--init", type=Path, metavar="RUN_DIR",
                        help="fine-tune: start from the policy of this finished run (same --algo)")
    options.add_trust_option(parser, "let --init start from the run's whole policy.zip (actor and critic) instead of "
                                     "its safe actor file: loading a zip unpickles it, which can run code; with "
                                     "--resume, lets a run started that way, killed before its first checkpoint, "
                                     "load the zip again")
    parser.add_argument("--hyper", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override a setting of the algorithm's YAML, e.g. hyperparams.learning_rate=3e-4 "
                             "or noise.sigma_start=0.05 (repeatable)")
    parser.add_argument("--demo-episodes", type=options.NON_NEGATIVE, metavar="N",
                        help="put N scripted (heuristic) scoops in the replay buffer before learning "
                             "(off-policy algorithms; default: the algorithm's YAML, demo_episodes, 0 when it has none)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    options.add_config_args(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    started = time.monotonic()
    # the config file first, before torch is imported: a hostile one fails in a fraction of a second
    config_keys = overrides_from_yaml(args.config) if args.config and not args.resume else {}
    for name in ("config.yaml", "hyperparams.yaml") if args.resume else ():  # a run's own YAML, likewise
        if (args.resume / name).is_file():
            read_yaml_file(args.resume / name, "run file")
    from autoscoop.training.checkpoints import read_run_json  # noqa: PLC0415 - torch is slow to import
    from autoscoop.training.run import TrainArgs, resume, train  # noqa: PLC0415 - torch is slow to import

    if args.resume:
        check_resume_options(args)
        if read_run_json(args.resume).get("status") == "finished" and selection_pending(args.resume):
            run_dir = args.resume  # trained; killed while its snapshots were being validated
        else:
            run_dir = resume(args.resume, progress=not args.no_progress, trust=args.trust)
    else:
        for name, value in DEFAULTS.items():
            if getattr(args, name) is None:
                setattr(args, name, value)
        if args.episodes is None:
            from autoscoop.training.settings import load_recipe  # noqa: PLC0415 - torch is slow to import

            args.episodes = int(load_recipe(args.algo, args.recipe).get("episodes", DEFAULT_EPISODES))
        # only the keys the file sets: its defaults must not undo the algorithm's own (reward.c_w)
        flat = {**config_keys, **parse_set_args(args.overrides)}
        run_dir = train(TrainArgs(algo=args.algo, episodes=args.episodes, seed=args.seed, n_envs=args.n_envs,
                                  overrides=flat, out=args.out, checkpoint_every=args.checkpoint_every,
                                  eval_every=args.eval_every, eval_episodes=args.eval_episodes,
                                  progress=not args.no_progress, init_from=args.init, trust=args.trust,
                                  hyper=parse_set_args(args.hyper), demo_episodes=args.demo_episodes,
                                  recipe=args.recipe))
    if selection_pending(run_dir):
        select_kept_policy(run_dir, progress=not args.no_progress)
    finish_run(run_dir, started, resumed=args.resume is not None)
    for line in kept_policy_lines(run_dir):
        print(line)
    print(f"run directory: {run_dir}")
    return 0


def finish_run(run_dir: Path, started: float, resumed: bool = False) -> None:
    """The kept policy as ONNX beside it (``policy.onnx``, checked against the torch actor), and the command's
    wall time in ``run.json``: ``command_wall_s`` adds this call's time (s, from ``started``, a
    ``time.monotonic()``) to what earlier calls on the run (``--resume``) recorded; ``export`` holds the
    parity check. Without onnx installed, or for an actor the safe format cannot hold, no file is written. Prints
    :func:`timing_line` (``resumed``: this call continued a run started before)."""
    from autoscoop.agents.policy_files import ActorPolicy, PolicyFileError  # noqa: PLC0415 - torch is slow to import
    from autoscoop.commands.export_cmd import export_policy  # noqa: PLC0415
    from autoscoop.training.checkpoints import lock_run_dir, read_run_json, write_run_json  # noqa: PLC0415

    if not (run_dir / "run.json").is_file():  # nothing was trained here
        return
    export: dict[str, object] = {}
    kept = run_dir / "policy.safetensors"
    try:
        report = export_policy(ActorPolicy(kept, name=run_dir.name), run_dir / "policy.onnx", str(kept), 2000)
        export = {"onnx": "policy.onnx", "max_abs_diff": report["max_abs_diff"], "passed": report["passed"]}
    except ImportError as error:  # the deploy extra is not installed
        print(f"no policy.onnx: {error}")
    except PolicyFileError as error:
        print(f"no policy.onnx: {error}")
    with lock_run_dir(run_dir):
        info = read_run_json(run_dir)
        info["command_wall_s"] = round(float(info.get("command_wall_s", 0.0)) + time.monotonic() - started, 1)
        if export:
            info["export"] = export
        write_run_json(run_dir, info)
    print(timing_line(time.monotonic() - started, float(info.get("wall_s", 0.0)), resumed))


def _seconds(value: float) -> str:
    return f"{value:.1f} s" if value < 10 else f"{value:.0f} s"


def timing_line(session_s: float, training_s: float, resumed: bool) -> str:
    """This command's wall time and the run's training time, in one sentence (s; training counts every session
    of a resumed run, to its last checkpoint for one that was killed)."""
    if resumed:
        return (f"this session took {_seconds(session_s)}; the run's training time so far is {_seconds(training_s)} "
                "(this session and the earlier ones together)")
    return f"this session took {_seconds(session_s)}, of which training took {_seconds(training_s)}"


def kept_policy_lines(run_dir: Path) -> list[str]:
    """What the run kept as its policy (``policy.*``), in words: which snapshot, from which episode, and its
    validation figures (the stress suite's when the recipe's selection chose it, else its periodic evaluation's:
    fill factor, success, cycle time of the successes, delivered fill). Says plainly when the run kept no policy
    that scoops (the best evaluation scored 0) or no evaluated one (no evaluation ran)."""
    import csv  # noqa: PLC0415
    import json  # noqa: PLC0415
    import math  # noqa: PLC0415

    from autoscoop.training.callbacks import PolicyEvaluator  # noqa: PLC0415 - torch is slow to import
    from autoscoop.training.checkpoints import SELECTION_FILE, read_run_json  # noqa: PLC0415

    if not (run_dir / "run.json").is_file():
        return []
    info = read_run_json(run_dir)
    episode = info.get("best_episode")
    if episode is None:
        return ["kept policy: none evaluated; no periodic evaluation ran (--eval-every 0), so policy.* is the "
                "policy at the end of training, unscored: `autoscoop eval --policy RUN` scores it"]
    evaluations = []
    if (run_dir / "evaluations.csv").is_file():
        with open(run_dir / "evaluations.csv", newline="") as handle:
            evaluations = list(csv.DictReader(handle))
    rows = [row for row in evaluations if int(row["episode"]) == int(episode)]
    seeds = f"{info.get('eval_episodes', 10)} episodes from seed {PolicyEvaluator.SEED}"
    which = (f"the best of {len(evaluations)} periodic evaluations" if len(evaluations) > 1
             else "its only periodic evaluation, at the end of training")
    lines = []
    if rows:
        row = rows[-1]
        cycle = float(row["cycle_time_s"]) if row["cycle_time_s"] not in ("", "nan") else math.nan
        shown = "no cycle time (none succeeded)" if math.isnan(cycle) else f"cycle time {cycle:.2f} s (successes)"
        lines.append(f"kept policy: the snapshot of episode {episode}, {which} ({seeds}): fill factor "
                     f"{float(row['fill_factor']):.3f}, success {float(row['success']):.2f}, {shown}, delivered fill "
                     f"{float(row['delivered_fill']):.3f}")
    selection = run_dir / SELECTION_FILE
    if info.get("selected_episode") is not None and selection.is_file():
        chosen = info["selected_episode"]
        record = json.loads(selection.read_text())
        figures = next((c for c in record.get("candidates", []) if c.get("name") == f"episode {chosen}"), None)
        if figures is not None:
            nominal = figures.get("by_case", {}).get("nominal", {})
            settings = record.get("settings", {})
            first = int(settings.get("seed", 0))
            lines = [f"kept policy: the snapshot of episode {chosen}, chosen on the stress suite ("
                     f"{settings.get('episodes')} episodes a case from seed {first}): {figures['cases_passed']} of "
                     f"{figures['cases']} cases hold, mean delivered fill {figures['mean_delivered_fill']:.3f}"
                     + (f"; nominal: fill factor {nominal['fill_factor_mean']:.3f}, success "
                        f"{nominal['success_rate']:.2f}" if nominal else "")]
    if float(info.get("best_score", 0.0)) <= 0.0 and info.get("selected_episode") is None:
        lines.append(f"the run kept no policy that scoops: its best periodic evaluation scored 0 (no episode "
                     f"succeeded); train for more episodes (this run had {info.get('episodes')})")
    return lines


def selection_pending(run_dir: Path) -> bool:
    """Whether the run's recipe has a ``selection`` section and the run has not made its choice yet."""
    from autoscoop.training.checkpoints import SELECTION_FILE, read_run_yaml  # noqa: PLC0415 - torch is slow to import
    from autoscoop.training.settings import selection_settings  # noqa: PLC0415

    spec_path = run_dir / "hyperparams.yaml"
    if not spec_path.is_file() or (run_dir / SELECTION_FILE).exists():
        return False
    return selection_settings(read_run_yaml(run_dir, "hyperparams.yaml") or {}) is not None


def last_world_snapshots(run_dir: Path, count: int) -> tuple[list[tuple[int, float, Path]], int]:
    """The run's ``count`` best evaluated snapshots of its last curriculum world by the periodic evaluation, as
    (episode, periodic score, actor file), and the episode from which that world ran (0 without a curriculum)."""
    from autoscoop.training.checkpoints import read_run_yaml, snapshot_candidates  # noqa: PLC0415 - torch is slow
    from autoscoop.training.settings import curriculum_stages  # noqa: PLC0415

    stages = curriculum_stages(read_run_yaml(run_dir, "hyperparams.yaml") or {})
    last_world_from = stages[-1][0] if stages else 0
    return snapshot_candidates(run_dir, count, last_world_from), last_world_from


def rank_run_snapshots(run_dir: Path, settings: SelectionSettings,
                       progress: bool = True) -> tuple[list[tuple[int, float, Path]], list[Ranked], int]:
    """Validate the run's best snapshots of its last curriculum world on every stress case, as its recipe's
    ``selection`` does (:mod:`autoscoop.evaluation.selection`), with ``settings``: how many candidates,
    episodes per case, first seed.

    Returns:
        (candidates as (episode, periodic score, path), the validated candidates best first, the episode from
        which the last world ran); both lists are empty when no snapshot was evaluated in that world.
    """
    import os  # noqa: PLC0415

    from autoscoop.evaluation.selection import rank_candidates  # noqa: PLC0415 - torch is slow to import

    candidates, last_world_from = last_world_snapshots(run_dir, settings.candidates)
    if not candidates:
        return [], [], last_world_from
    ranked = rank_candidates([(f"episode {episode}", path) for episode, _, path in candidates],
                             settings.episodes, settings.seed, workers=min(os.cpu_count() or 1, 4),
                             progress=progress)
    return candidates, ranked, last_world_from


def select_kept_policy(run_dir: Path, progress: bool = True) -> None:
    """The recipe's ``selection``: validate the run's best snapshots of its last curriculum world on every stress
    case and keep the one that falls least short (:func:`rank_run_snapshots`); ``selection.json``
    records each candidate's figures."""
    import time  # noqa: PLC0415

    from autoscoop.training.checkpoints import (  # noqa: PLC0415 - torch is slow to import
        keep_snapshot,
        lock_run_dir,
        read_run_yaml,
    )
    from autoscoop.training.settings import selection_settings  # noqa: PLC0415

    settings = selection_settings(read_run_yaml(run_dir, "hyperparams.yaml"))
    started = time.time()
    with lock_run_dir(run_dir):
        candidates, ranked, last_world_from = rank_run_snapshots(run_dir, settings, progress=progress)
        if not candidates:
            print(f"selection: no evaluated snapshot after episode {last_world_from}; the run keeps its policy")
            return
        periodic = {path: score for _, score, path in candidates}
        best = ranked[0]
        episode = next(number for number, _, path in candidates if path == best.path)
        record = {"settings": {"candidates": settings.candidates, "episodes": settings.episodes,
                               "seed": settings.seed, "after_episode": last_world_from},
                  "selected_episode": episode, "wall_s": round(time.time() - started, 1),
                  "candidates": [{**r.summary(), "periodic_score": periodic[r.path]} for r in ranked]}
        keep_snapshot(run_dir, episode, record)
    print(f"selection: kept the snapshot of episode {episode} ({best.cases_passed} of {len(best.rows)} cases hold "
          f"on validation seeds {settings.seed}-{settings.seed + settings.episodes - 1}, shortfall {best.shortfall:.3f})")


def check_resume_options(args: argparse.Namespace) -> None:
    """Refuse what ``--resume`` would otherwise ignore: ``--episodes``, the options of :data:`NOT_WITH_RESUME`,
    and those of :data:`RECORDED` with another value than the run's ``run.json`` records (the same value is
    harmless and taken). ``--no-progress`` is honoured.

    Raises:
        ValueError: naming the option and, for a recorded setting, both values and the ``run.json``.
    """
    info_path = args.resume / "run.json"
    if args.episodes is not None:
        raise ValueError(f"--episodes cannot be given with --resume: a resumed run keeps the episode count "
                         f"recorded in {info_path}")
    given = [option for name, option in NOT_WITH_RESUME.items() if getattr(args, name) not in (None, False, [])]
    if given:
        raise ValueError(f"{', '.join(given)} cannot be given with --resume: it continues {args.resume} with the "
                         f"settings it recorded ({args.resume / 'config.yaml'}, {args.resume / 'hyperparams.yaml'}, "
                         f"{info_path}); start a new run (--out) to change them")
    asked = {name: getattr(args, name) for name in RECORDED if getattr(args, name) is not None}
    if not asked:
        return
    from autoscoop.training.checkpoints import read_run_json  # noqa: PLC0415 - torch is slow to import

    info = read_run_json(args.resume)
    for name, value in asked.items():
        if value != info.get(name):
            raise ValueError(f"{RECORDED[name]} {value} does not match the run being resumed: {info_path} records "
                             f"{name} = {info.get(name)!r}; a resumed run keeps its settings (leave {RECORDED[name]} out)")
