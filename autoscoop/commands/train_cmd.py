"""``autoscoop train``: train the paper's DDPG controller (or TD3, SAC, PPO) into a run directory."""

from __future__ import annotations

import argparse
from pathlib import Path

from autoscoop.commands import add_config_args, seed_int
from autoscoop.core.config import overrides_from_yaml, parse_set_args

DEFAULT_EPISODES = 800
"""training episodes of a new run when ``--episodes`` is not given (the paper's)."""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("train", help="train a controller", description=__doc__)
    parser.add_argument("--algo", default="ddpg", choices=["ddpg", "td3", "sac", "ppo"],
                        help="algorithm (default ddpg, the paper's); settings in autoscoop/training/hyperparams/ALGO.yaml")
    parser.add_argument("--episodes", type=int, default=None,
                        help=f"training episodes (default {DEFAULT_EPISODES}, as in the paper; "
                             "not with --resume: a resumed run keeps its recorded count)")
    parser.add_argument("--seed", type=seed_int, default=0, help="random seed (0 or more)")
    parser.add_argument("--n-envs", type=int, default=1, help="parallel simulators in subprocesses (default 1)")
    parser.add_argument("--checkpoint-every", type=int, default=50, help="episodes between checkpoints (default 50)")
    parser.add_argument("--eval-every", type=int, default=50,
                        help="episodes between evaluations of the deterministic policy; the best is kept (0: keep the last)")
    parser.add_argument("--eval-episodes", type=int, default=10, help="episodes per evaluation (default 10)")
    parser.add_argument("--out", type=Path, help="run directory (default runs/ALGO-sSEED-TIME)")
    parser.add_argument("--resume", type=Path, metavar="RUN_DIR", help="continue an interrupted run")
    parser.add_argument("--init", type=Path, metavar="RUN_DIR",
                        help="fine-tune: start from the policy of this finished run (same --algo)")
    parser.add_argument("--trust", action="store_true",
                        help="let --init load a policy.zip its run.json does not vouch for (zips run pickle)")
    parser.add_argument("--hyper", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override a setting of the algorithm's YAML, e.g. hyperparams.learning_rate=3e-4 "
                             "or noise.sigma_start=0.05 (repeatable)")
    parser.add_argument("--demo-episodes", type=int, metavar="N",
                        help="put N scripted (heuristic) scoops in the replay buffer before learning "
                             "(off-policy algorithms; default: the algorithm's YAML, demo_episodes, 0 when it has none)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_config_args(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from autoscoop.training.run import TrainArgs, resume, train  # noqa: PLC0415 - torch is slow to import

    if args.resume:
        if args.episodes is not None:
            raise ValueError(f"--episodes cannot be given with --resume: a resumed run keeps the episode count "
                             f"recorded in {args.resume / 'run.json'}")
        run_dir = resume(args.resume, progress=not args.no_progress)
    else:
        if args.episodes is None:
            args.episodes = DEFAULT_EPISODES
        if args.episodes < 1 or args.n_envs < 1 or args.checkpoint_every < 1 or args.eval_episodes < 1:
            raise ValueError("--episodes, --n-envs, --checkpoint-every and --eval-episodes must be at least 1")
        if args.eval_every < 0:
            raise ValueError("--eval-every must be 0 (off) or more")
        if args.demo_episodes is not None and args.demo_episodes < 0:
            raise ValueError("--demo-episodes must be 0 (none) or more")
        # only the keys the file sets: its defaults must not undo the algorithm's own (reward.c_w)
        flat = overrides_from_yaml(args.config) if args.config else {}
        flat.update(parse_set_args(args.overrides))
        run_dir = train(TrainArgs(algo=args.algo, episodes=args.episodes, seed=args.seed, n_envs=args.n_envs,
                                  overrides=flat, out=args.out, checkpoint_every=args.checkpoint_every,
                                  eval_every=args.eval_every, eval_episodes=args.eval_episodes,
                                  progress=not args.no_progress, init_from=args.init, trust=args.trust,
                                  hyper=parse_set_args(args.hyper), demo_episodes=args.demo_episodes))
    print(f"run directory: {run_dir}")
    return 0
