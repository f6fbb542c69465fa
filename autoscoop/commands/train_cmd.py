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
    finish_run(run_dir, started)
    print(f"run directory: {run_dir}")
    return 0


def finish_run(run_dir: Path, started: float) -> None:
    """The kept policy as ONNX beside it (``policy.onnx``, checked against the torch actor), and the command's
    wall time in ``run.json``: ``command_wall_s`` adds this call's time (s, from ``started``, a
    ``time.monotonic()``) to what earlier calls on the run (``--resume``) recorded; ``export`` holds the
    parity check. Without onnx installed, or for an actor the safe format cannot hold, no file is written."""
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
    print(f"command wall time: {info['command_wall_s']:.0f} s (training {info.get('wall_s', 0):.0f} s)")


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
