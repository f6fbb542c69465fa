"""``autoscoop adapt``: fine-tune a trained controller for a target world instead of training one from scratch.

The target world is what ``--set``/``--config`` lay over the policy's training config: a material
(``pile.particle_mass_kg``, ``pile.friction``), a pile (``pile.angle_deg``), a sensor link (``sensor.*``), a
randomisation preset (``randomize.preset``). The run starts from the policy's actor and the critic that trained
it (``default`` ships both), trains in the target world and in the policy's own last world side by side (for
a policy of another machine, ``--from-machine``: this machine's nominal and last worlds, a warm start), then
validates its best snapshots and the starting policy on the target world and on every stress case (seeds 30000
on, apart from the seeds 0-99 reports use) and ranks them by how far they fall short of the stress thresholds
and lose ground where the starting policy held. A snapshot that ranks above the starting policy is run again
beside it on the next seeds, and kept only if that confirmation is ``--confidence`` sure (paired bootstrap)
that it scores better; otherwise the run keeps the policy it started from. The run directory is a training
run's, with ``policy.onnx`` exported at the end; ``--resume RUN`` continues one that was cut.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from autoscoop.commands import options
from autoscoop.core.config import overrides_from_yaml, parse_set_args, read_yaml_file

if TYPE_CHECKING:  # torch is slow to import: these are imported where they run
    from autoscoop.evaluation.selection import RankedForTarget
    from autoscoop.evaluation.stress import StressCase

CONFIDENCE = 0.95
"""how sure the confirmation must be, by default, that the validation's best snapshot scores better than the
policy the run started from before the run keeps it: the share of paired bootstrap draws in which it does."""
VALIDATION_WORKERS = 2
"""worker processes of the validation and the confirmation by default: the two cores the training used."""
VALIDATION_SEED = 30_000
"""first seed of the validation that picks the kept snapshot: apart from the periodic evaluation's 10000 on, the
recipes' selection's 20000 on and the reports' 0-99."""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("adapt", help="fine-tune a trained controller for a target world",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    options.add_policy_option(parser, accepts="default, a training run directory, or NAME.safetensors beside "
                                              "NAME.critic.safetensors")
    parser.add_argument("--from-machine", metavar="NAME|DIR",
                        help="the machine the policy was trained on, when it is not --machine's: a warm start of this "
                             "machine's controller from it (--policy default: that machine's shipped controller); "
                             "both worlds are this machine's")
    parser.add_argument("--length-scale", type=options.NumberIn(0.1, 10.0), metavar="S",
                        help="with --from-machine: this machine's size over that one's, by which the policy's input is "
                             "scaled, in [0.1, 10] (default: the ratio of their lift arms' lengths)")
    options.add_episodes_option(parser, default=400, what="training episodes, both worlds together")
    options.add_seed_option(parser, default=0, what="random seed of the run")
    options.add_out_option(parser, None, "run directory (default runs/adapt-sSEED-TIME)")
    parser.add_argument("--resume", type=Path, metavar="RUN_DIR", help="continue an interrupted adapt run")
    parser.add_argument("--target-envs", type=options.POSITIVE, default=1, metavar="N",
                        help="simulators in the target world (default 1)")
    parser.add_argument("--held-envs", type=options.NON_NEGATIVE, default=1, metavar="N",
                        help="simulators in the policy's own last world, to keep what it holds (default 1; 0: none)")
    parser.add_argument("--critic-warmup-steps", type=options.NON_NEGATIVE, default=500, metavar="N",
                        help="gradient steps before the actor moves, while the critic learns the target world "
                             "(default 500)")
    parser.add_argument("--actor-lr-scale", type=options.NumberIn(1e-4, 1.0), default=0.1, metavar="X",
                        help="the actor's learning rate as a fraction of the critic's, in [0.0001, 1] (default 0.1)")
    parser.add_argument("--anchor-alpha", type=options.NumberIn(0.0, 1000.0), default=2.5, metavar="X",
                        help="weight of the critic against the pull back to the starting actor (TD3+BC's alpha), "
                             "in [0, 1000] (default 2.5; 0: no pull)")
    parser.add_argument("--noise-sigma", type=options.NumberIn(0.0, 1.0), default=0.05, metavar="X",
                        help="exploration noise, standard deviation in action units, in [0, 1] (default 0.05)")
    parser.add_argument("--eval-every", type=options.POSITIVE, default=25, metavar="N",
                        help="episodes between evaluations in the target world (default 25)")
    parser.add_argument("--eval-episodes", type=options.POSITIVE, default=10, metavar="N",
                        help="episodes per periodic evaluation (default 10)")
    parser.add_argument("--checkpoint-every", type=options.POSITIVE, default=50, metavar="N",
                        help="episodes between checkpoints, for --resume (default 50)")
    parser.add_argument("--candidates", type=options.NON_NEGATIVE, default=3, metavar="N",
                        help="best snapshots by the periodic evaluation validated beside the starting policy "
                             "(default 3; 0: keep the best periodic evaluation)")
    parser.add_argument("--validation-episodes", type=options.POSITIVE, default=20, metavar="N",
                        help="episodes per world in the validation, and again in the confirmation (default 20)")
    parser.add_argument("--confidence", type=options.NumberIn(0.0, 1.0), default=CONFIDENCE, metavar="P",
                        help="how sure the confirmation on fresh seeds must be that the best snapshot scores better "
                             f"than the starting policy before the run keeps it, in [0, 1] (default {CONFIDENCE}; "
                             "0: keep the validation's best without a confirmation)")
    options.add_workers_option(parser, default=VALIDATION_WORKERS)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    options.add_config_args(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    started = time.monotonic()
    config_keys = overrides_from_yaml(args.config) if args.config and not args.resume else {}
    if args.resume:
        given = [flag for flag, value in (("--out", args.out), ("--config", args.config),
                                          ("--set", args.overrides), ("--from-machine", args.from_machine),
                                          ("--length-scale", args.length_scale)) if value]
        if given:
            raise ValueError(f"--resume continues {args.resume} with its recorded settings; drop {', '.join(given)}")
        for name in ("config.yaml", "held.yaml", "hyperparams.yaml"):
            if (args.resume / name).is_file():
                read_yaml_file(args.resume / name, "run file")
    if args.length_scale is not None and not args.from_machine:
        raise ValueError("--length-scale scales a policy of another machine; give it with --from-machine")
    from autoscoop.training.adapt import AdaptArgs, adapt, resume_adapt  # noqa: PLC0415 - torch is slow to import
    from autoscoop.training.checkpoints import read_run_json  # noqa: PLC0415

    if args.resume:
        info = read_run_json(args.resume)
        run_dir = args.resume if info.get("status") == "finished" else resume_adapt(args.resume, not args.no_progress)
    else:
        overrides = {**config_keys, **parse_set_args(args.overrides)}
        run_dir = adapt(AdaptArgs(policy=args.policy, overrides=overrides, episodes=args.episodes, seed=args.seed,
                                  target_envs=args.target_envs, held_envs=args.held_envs,
                                  critic_warmup_steps=args.critic_warmup_steps, actor_lr_scale=args.actor_lr_scale,
                                  anchor_alpha=args.anchor_alpha,
                                  noise_sigma=args.noise_sigma, eval_every=args.eval_every,
                                  eval_episodes=args.eval_episodes, out=args.out,
                                  checkpoint_every=args.checkpoint_every, from_machine=args.from_machine,
                                  length_scale=args.length_scale,
                                  progress=not args.no_progress))
    if not (run_dir / "selection.json").exists():
        select_adapted(run_dir, args.candidates, args.validation_episodes, args.workers, not args.no_progress,
                       args.confidence)
    from autoscoop.commands.train_cmd import finish_run  # noqa: PLC0415

    finish_run(run_dir, started)
    info = read_run_json(run_dir)
    print(f"adapt: {info['episodes']} training episodes, {info.get('scoops_simulated', '?')} simulated scoops in all, "
          f"{info.get('command_wall_s', info.get('wall_s'))} s")
    print(f"run directory: {run_dir}")
    return 0


def select_adapted(run_dir: Path, candidates: int, episodes: int, workers: int, progress: bool,
                   confidence: float = CONFIDENCE) -> None:
    """Validate the starting policy and the run's ``candidates`` best snapshots on the target world and every
    stress case (:func:`autoscoop.evaluation.selection.rank_for_target`); when a snapshot ranks first, confirm it
    beside the starting policy on the next ``episodes`` seeds and keep it only if the confirmation is
    ``confidence`` sure it scores better (:func:`~autoscoop.evaluation.selection.confidence_of_gain`; 0: no
    confirmation), else keep the start; write ``selection.json`` and the count of simulated scoops to ``run.json``."""
    from autoscoop.core.config import from_dict  # noqa: PLC0415
    from autoscoop.evaluation.selection import rank_for_target  # noqa: PLC0415 - torch is slow to import
    from autoscoop.evaluation.stress import STRESS_THRESHOLDS, StressCase  # noqa: PLC0415
    from autoscoop.training.checkpoints import (  # noqa: PLC0415
        keep_snapshot,
        lock_run_dir,
        read_run_json,
        read_run_yaml,
        snapshot_candidates,
        write_run_json,
    )

    started = time.time()
    spec = read_run_yaml(run_dir, "hyperparams.yaml")
    overrides = dict(spec["adapt"]["target_overrides"])
    from_dict(read_run_yaml(run_dir, "config.yaml"))  # the run's world still reads
    with lock_run_dir(run_dir):
        info = read_run_json(run_dir)
        start = run_dir / "evaluated" / "episode_00000.safetensors"
        best = [(episode, path) for episode, _, path in snapshot_candidates(run_dir, candidates, 1)] if candidates else []
        ranked_names = [("start", start), *((f"episode {episode}", path) for episode, path in best)]
        periodic = info["eval_episodes"] * (info["episodes"] // info["eval_every"] + 1)
        validated = 0
        if candidates and start.is_file():
            target = StressCase("target", f"target world ({', '.join(f'{k}={v}' for k, v in overrides.items())})",
                                overrides, STRESS_THRESHOLDS)
            ranked = rank_for_target(ranked_names, target, episodes, VALIDATION_SEED, workers=workers, progress=progress)
            validated = len(ranked_names) * len(ranked[0].rows) * episodes
            kept = ranked[0]
            confirmation = None
            if kept.path != start and confidence > 0.0:
                confirmation = confirm_candidate(start, kept, target, episodes, workers, progress, confidence)
                validated += 2 * len(kept.rows) * episodes
                if not confirmation["confirmed"]:
                    kept = next(r for r in ranked if r.path == start)
            episode = 0 if kept.path == start else next(e for e, path in best if path == kept.path)
            record = {"settings": {"candidates": candidates, "episodes": episodes, "seed": VALIDATION_SEED,
                                   "confidence": confidence, "target_overrides": overrides},
                      "selected_episode": episode, "wall_s": round(time.time() - started, 1),
                      "candidates": [r.summary() for r in ranked], "confirmation": confirmation}
            keep_snapshot(run_dir, episode, record)
            print(f"selection: kept {kept.name} (target world {'holds' if kept.target_passed else 'FAILS'}, "
                  f"{kept.cases_passed - kept.target_passed} of {len(kept.rows) - 1} stress cases hold on validation "
                  f"seeds {VALIDATION_SEED}-{VALIDATION_SEED + episodes - 1}; ground lost {kept.regression:.2f})")
        info = read_run_json(run_dir)
        info["scoops_simulated"] = int(info["episodes"] + periodic + validated)
        write_run_json(run_dir, info)


def confirm_candidate(start: Path, best: RankedForTarget, target: StressCase, episodes: int, workers: int,
                      progress: bool, confidence: float) -> dict[str, Any]:
    """Run the validation's ``best`` and the starting policy again on the ``episodes`` seeds after the validation's, on the target world and every stress case,
    and return ``selection.json``'s ``confirmation``: how sure it is that ``best`` scores better
    (:func:`~autoscoop.evaluation.selection.confidence_of_gain`), ``confirmed`` when at least ``confidence``, and
    both policies' figures. Fresh seeds, because the validation's best is the best of several on its seeds."""
    from autoscoop.evaluation.selection import confidence_of_gain, rank_for_target  # noqa: PLC0415

    seed = VALIDATION_SEED + episodes
    if progress:
        print(f"confirmation: {best.name} beside the start on seeds {seed}-{seed + episodes - 1}", flush=True)
    again = {r.name: r for r in rank_for_target([("start", start), (best.name, best.path)], target, episodes, seed,
                                                workers=workers, progress=False)}
    sure = confidence_of_gain(again["start"].rows, again[best.name].rows)
    if progress:
        print(f"confirmation: {best.name} scores better than the start in {sure:.0%} of paired bootstrap draws "
              f"({confidence:.0%} required): {'kept' if sure >= confidence else 'the start kept'}", flush=True)
    return {"seed": seed, "episodes": episodes, "candidate": best.name, "confidence": sure, "required": confidence,
            "confirmed": sure >= confidence, "start": again["start"].summary(),
            "candidate_figures": again[best.name].summary()}
