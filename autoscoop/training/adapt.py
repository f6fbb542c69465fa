"""Fine-tune a trained controller for a target world (``autoscoop adapt``): its run directory, model and resume.

An adapt run starts from a policy's actor and the critic(s) that trained it (:mod:`autoscoop.agents.critic_files`)
instead of random weights. Its simulators are split between the **target world** (the policy's training config
with the user's ``--set``/``--config`` laid over it) and the **held world** (the last world of the policy's own
recipe: the randomised ``robot`` world for the shipped policy), so that what the controller already does is
trained on while it learns the new. A policy of another machine (``from_machine``) is a warm start: its actor and
critic, their input scaled for this machine's size (:mod:`autoscoop.agents.rescale`; the run's
``start.safetensors``), start this machine's controller, and both worlds are this machine's (its nominal world
with the policy's recipe's settings, and that recipe's last world). The actor holds still for the first
``critic_warmup_steps`` gradient steps, while the critic learns the target world, then moves at ``actor_lr_scale`` of the critic's learning rate
(:class:`autoscoop.agents.optimizers.HeldAdam`). Exploration noise is small and constant. The periodic evaluation
scores each snapshot in the target world; which snapshot the run keeps is chosen afterwards on a validation of
both worlds (``autoscoop adapt`` does it, :mod:`autoscoop.evaluation.selection`).

The run directory is a training run's (:mod:`autoscoop.training.run`), with ``config.yaml`` the target world,
``held.yaml`` the held world and ``run.json``'s ``adapt`` section what the run started from.
"""

from __future__ import annotations

import copy
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
import yaml

from autoscoop.agents.anchored import AnchoredDDPG
from autoscoop.agents.critic_files import critic_into_sb3, critic_path_for, read_critic_sidecar
from autoscoop.agents.loading import DEFAULT_POLICY, default_policy_path
from autoscoop.agents.optimizers import HeldAdam
from autoscoop.agents.policy_files import PolicyFileError, load_actor, save_actor, sha256_of
from autoscoop.agents.rescale import rescale_critics, rescaled_actor
from autoscoop.core import kinematics
from autoscoop.core.config import ScoopConfig, from_dict, save_yaml
from autoscoop.core.machine import (
    FILES_BEFORE_MACHINES,
    MachineError,
    load_machine,
    refuse_other_machine,
    shipped_machines,
)
from autoscoop.core.safe_files import write_text_atomically
from autoscoop.core.version import __version__, dependency_versions
from autoscoop.training.checkpoints import (
    CRITIC_FILE,
    clear_run_outputs,
    find_checkpoint,
    load_checkpoint,
    load_init_weights,
    lock_run_dir,
    read_run_json,
    read_run_yaml,
    refuse_run_of_other_machine,
    restore_to_checkpoint,
    write_run_json,
)
from autoscoop.training.factories import history_steps, make_mixed_vec_env
from autoscoop.training.run import build_model, privileged_critic, set_bookkeeping, train_model
from autoscoop.training.settings import config_at

ADAPT_RECIPE = "adapt"
"""``run.json``'s ``recipe`` of an adapt run."""
LEARNING_STARTS = 128
"""transitions of random actions before learning starts (one batch of the recipes' DDPG)."""
DROPPED_KEYS = ("curriculum", "selection", "demo_episodes", "learning_rate_end", "summary", "base")
"""what of the policy's recipe an adapt run does not take: it starts trained, in its two worlds."""


@dataclass
class AdaptArgs:
    """Arguments of one adapt run."""

    policy: str = DEFAULT_POLICY
    """``default``, a training run directory, or an actor ``NAME.safetensors`` beside ``NAME.critic.safetensors``."""
    overrides: dict[str, Any] = field(default_factory=dict)
    """the target world: dotted config keys laid over the policy's training config."""
    episodes: int = 400
    """training episodes, both worlds together."""
    seed: int = 0
    """seed of the noise, the replay sampling and the environments."""
    target_envs: int = 1
    """simulators in the target world."""
    held_envs: int = 1
    """simulators in the held world (0: the target world alone)."""
    critic_warmup_steps: int = 500
    """gradient steps (one after each step of all simulators) before the actor moves."""
    actor_lr_scale: float = 0.1
    """the actor's learning rate as a fraction of the critic's, in (0, 1]."""
    anchor_alpha: float = 2.5
    """weight of the critic against the pull back to the starting actor (:class:`AnchoredDDPG`); 0: no pull."""
    noise_sigma: float = 0.05
    """standard deviation of the exploration noise (Ornstein-Uhlenbeck as the recipe's, constant)."""
    eval_every: int = 25
    """episodes between evaluations in the target world (each snapshot kept in ``evaluated/``)."""
    eval_episodes: int = 10
    """episodes per periodic evaluation."""
    checkpoint_every: int = 50
    """episodes between checkpoints (for ``--resume``)."""
    out: Path | None = None
    """run directory; default runs/adapt-sSEED-TIME."""
    progress: bool = True
    """show a progress bar."""
    command: str | None = None
    """the command ``run.json`` records; ``None``: this process's command line."""
    from_machine: str | None = None
    """the machine (name or folder) the policy was trained on when it is not this process's: a warm start of this
    machine's controller from another machine's (``None``: this machine's policy)."""
    length_scale: float | None = None
    """with ``from_machine``: this machine's size over the policy's, for the scaling of the input (``None``: the ratio
    of their lift arms' lengths)."""


@dataclass(frozen=True)
class AdaptSource:
    """The policy an adapt run starts from: its actor file, its critic file and the critic's sidecar."""

    name: str
    actor: Path
    critic: Path | None
    """``None``: a fresh critic (fitting a critic to a policy that shipped without one, ``release/fit_critic.py``)."""
    critic_meta: dict[str, Any]
    """the critic's sidecar: ``spec`` (the recipe), ``config`` (the base world), ``held_config`` (the last world)."""
    machine: str = ""
    """the machine the policy was trained on; another than this process's makes the run a warm start across machines."""
    length_scale: float = 1.0
    """this machine's size over that machine's: the actor's and critic's input are scaled by it (1: the same machine)."""

    @property
    def across_machines(self) -> bool:
        """Whether the policy was trained on another machine than the one this process runs."""
        return bool(self.machine) and self.machine != kinematics.MACHINE.name


def adapt_source(policy: str, from_machine: str | None = None, length_scale: float | None = None) -> AdaptSource:
    """The actor and critic files of ``policy``, checked now (before any simulation).

    Args:
        policy: ``default`` (the shipped controller of ``from_machine``, else of this machine), a training run
            directory, or an actor file beside its critic.
        from_machine: the machine (name or folder) the policy was trained on, when it is not this process's.
        length_scale: this machine's size over ``from_machine``'s (``None``: the ratio of their lift arms' lengths).

    Raises:
        PolicyFileError: no critic beside the actor, a critic of another actor, or files that do not load.
        MachineError: a policy trained on another machine than this process's (or than ``from_machine``); the
            message names ``--from-machine``.
        ValueError: a policy of a kind that has no critic (``heuristic``, ONNX, a zip) or that does not exist.
    """
    path = Path(policy)
    origin = load_machine(from_machine) if from_machine else kinematics.MACHINE
    if policy == DEFAULT_POLICY:
        actor = default_policy_path(origin)
    elif (path / "run.json").is_file():
        actor = path / "policy.safetensors"
    elif path.suffix == ".safetensors" and path.is_file():
        actor = path
    else:
        raise ValueError(f"--policy {policy}: adapt starts from a policy and the critic that trained it: "
                         "'default', a training run directory, or NAME.safetensors beside NAME.critic.safetensors "
                         "(the scripted baseline, ONNX files and zips carry no critic)")
    critic = path / CRITIC_FILE if actor.parent == path else critic_path_for(actor)
    if not critic.is_file():
        raise PolicyFileError(f"--policy {policy}: no critic beside its actor (expected {critic}); adapt fine-tunes "
                              "the actor together with the critic that trained it. `autoscoop train` writes "
                              f"{CRITIC_FILE} for every run of an off-policy algorithm")
    _, actor_meta = load_actor(actor)
    try:
        refuse_other_machine(actor_meta, origin, f"--policy {policy}")
    except MachineError as error:
        if from_machine:
            raise
        recorded = str(actor_meta.get("machine") or FILES_BEFORE_MACHINES)
        raise MachineError(f"{error}; or start this machine's controller from it with --from-machine "
                           f"{recorded if recorded in shipped_machines() else 'DIR'} (a warm start across "
                           "machines)") from None
    meta = read_critic_sidecar(critic)
    belongs = {sha256_of(actor)} | ({sha256_of(path / "last.safetensors")} if (path / "last.safetensors").is_file() else set())
    # a shipped actor that is its run's kept snapshot, beside the critic of the run's last actor, as a run
    # directory pairs them: its sidecar names the kept actor (``kept_actor_sha256``)
    if meta["actor_sha256"] not in belongs and meta.get("kept_actor_sha256") != sha256_of(actor):
        raise PolicyFileError(f"--policy {policy}: the critic {critic} was trained with another actor "
                              f"(SHA-256 {meta['actor_sha256'][:12]}...)")
    scale = 1.0
    if origin.name != kinematics.MACHINE.name:
        scale = float(length_scale) if length_scale is not None else kinematics.MACHINE.arm.length_m / origin.arm.length_m
    return AdaptSource(policy, actor, critic, meta, origin.name, scale)


def adapt_worlds(source: AdaptSource, overrides: dict[str, Any]) -> tuple[ScoopConfig, ScoopConfig]:
    """The target world (the policy's training config with ``overrides``) and the held world (the last world of
    the policy's recipe, as its critic file records it). For a policy of another machine both are this machine's:
    its nominal world with the recipe's ``env`` settings (what ``autoscoop train`` would start from), with
    ``overrides``, and that world at the end of the recipe's curriculum. A key that does not exist or a value out
    of range is a :class:`ConfigError` now."""
    spec = source.critic_meta["spec"]
    if source.across_machines:
        base = ScoopConfig().with_overrides(dict(spec.get("env") or {}))
        return base.with_overrides(overrides), config_at(base, spec, 1 << 30)
    base = from_dict(source.critic_meta["config"])
    held = source.critic_meta.get("held_config")
    held = from_dict(held) if isinstance(held, dict) else config_at(base, spec, 1 << 30)
    return base.with_overrides(overrides), held


def adapt_spec(source: AdaptSource, args: AdaptArgs) -> dict[str, Any]:
    """The run's YAML: the policy's recipe without its curriculum, demonstrations and selection, with constant
    small noise, ``episodes`` and an ``adapt`` section with the fine-tuning settings."""
    spec = {key: value for key, value in copy.deepcopy(source.critic_meta["spec"]).items() if key not in DROPPED_KEYS}
    spec["episodes"] = args.episodes
    # a trained actor acts from the first step: only one batch of the uniform random actions SB3 takes before
    # learning starts (they show the critic what the actor does not do)
    hyperparams = spec.setdefault("hyperparams", {})
    hyperparams["learning_starts"] = min(int(hyperparams.get("learning_starts", LEARNING_STARTS)), LEARNING_STARTS)
    if spec.get("noise"):
        spec["noise"].update(sigma_start=args.noise_sigma, sigma_end=args.noise_sigma)
    spec["adapt"] = {"critic_warmup_steps": args.critic_warmup_steps, "actor_lr_scale": args.actor_lr_scale,
                     "anchor_alpha": args.anchor_alpha,
                     "target_envs": args.target_envs, "held_envs": args.held_envs,
                     "target_overrides": dict(args.overrides)}
    return spec


def check_adapt_args(args: AdaptArgs) -> None:
    """Refuse settings out of range, naming the option and the range (before anything is built)."""
    if args.target_envs < 1 or args.held_envs < 0 or args.target_envs + args.held_envs > 8:
        raise ValueError(f"target_envs must be 1 or more and held_envs 0 or more, 8 simulators at most; got "
                         f"{args.target_envs} and {args.held_envs}")
    if not 0.0 < args.actor_lr_scale <= 1.0:
        raise ValueError(f"actor_lr_scale = {args.actor_lr_scale} is out of range; allowed (0, 1]")
    if not 0.0 <= args.noise_sigma <= 1.0:
        raise ValueError(f"noise_sigma = {args.noise_sigma} is out of range; allowed [0, 1]")
    if not 0.0 <= args.anchor_alpha <= 1000.0:
        raise ValueError(f"anchor_alpha = {args.anchor_alpha} is out of range; allowed [0, 1000]")
    if args.critic_warmup_steps < 0:
        raise ValueError(f"critic_warmup_steps = {args.critic_warmup_steps} must be 0 or more")


def _default_run_dir(seed: int) -> Path:
    return Path("runs") / f"adapt-s{seed}-{time.strftime('%Y%m%d-%H%M%S')}"


def adapt(args: AdaptArgs, source: AdaptSource | None = None) -> Path:
    """Start an adapt run into a new run directory and train it to the end; return the directory. Everything
    that can be refused (the policy, its critic, the world's keys, the settings) is refused before a simulator
    starts or a directory is made. ``source``: the policy to start from (default: :func:`adapt_source` of
    ``args.policy``)."""
    check_adapt_args(args)
    source = source or adapt_source(args.policy, args.from_machine, args.length_scale)
    target, held = adapt_worlds(source, args.overrides)
    spec = adapt_spec(source, args)
    run_dir = Path(args.out) if args.out else _default_run_dir(args.seed)
    created = not run_dir.exists()
    run_dir.mkdir(parents=True, exist_ok=True)
    try:
        with lock_run_dir(run_dir):
            if (run_dir / "run.json").exists():
                raise ValueError(f"{run_dir} already holds a run; use --resume {run_dir} to continue it, or another --out")
            info = {"algo": source.critic_meta.get("algo", "ddpg"), "recipe": ADAPT_RECIPE, "seed": args.seed,
                    "episodes": args.episodes, "n_envs": args.target_envs + args.held_envs,
                    "autoscoop_version": __version__, "command": args.command or " ".join(sys.argv),
                    "torch": torch.__version__, "dependencies": dependency_versions(),
                    "checkpoint_every": args.checkpoint_every, "eval_every": args.eval_every,
                    "eval_episodes": args.eval_episodes, "demo_episodes": 0,
                    "state_frame": "level" if target.sensor.level_with_imu else "chassis",
                    "status": "running", "wall_s": 0.0,
                    "init_from": str(source.actor.resolve()), "init_sha256": sha256_of(source.actor),
                    "adapt": {"policy": source.name, "from_machine": source.machine,
                              "length_scale": round(source.length_scale, 6),
                              "critic_from": str(source.critic.resolve()) if source.critic else None,
                              "critic_sha256": source.critic_meta.get("sha256")}}
            if source.across_machines:
                start = write_rescaled_start(source, run_dir / START_FILE)
                info.update(init_from=str(start.resolve()), init_sha256=sha256_of(start))
            model = adapt_model(run_dir, target, held, spec, info)
            save_yaml(target, run_dir / "config.yaml")
            save_yaml(held, run_dir / "held.yaml")
            write_text_atomically(run_dir / "hyperparams.yaml", yaml.safe_dump(spec, sort_keys=False))
            write_run_json(run_dir, info)
            return train_model(run_dir, target, spec, info, done=0, model=model, progress=args.progress)
    except BaseException:
        if created and not (run_dir / "run.json").exists():
            shutil.rmtree(run_dir, ignore_errors=True)
        raise


START_FILE = "start.safetensors"
"""the actor a warm start across machines begins from, in its run directory: the other machine's actor, rescaled."""


def write_rescaled_start(source: AdaptSource, path: Path) -> Path:
    """Write ``source``'s actor with its input scaled for this machine (:func:`rescaled_actor`), as this machine's."""
    actor, meta = load_actor(source.actor)
    kept = {key: value for key, value in meta.items()
            if key not in ("format", "layers", "output", "sha256", "machine", "machine_sha256", "history_steps")}
    return save_actor(rescaled_actor(actor, source.length_scale), path,
                      {**kept, "rescaled_from": {"machine": source.machine, "sha256": sha256_of(source.actor),
                                                 "length_scale": round(source.length_scale, 6)}})


def adapt_model(run_dir: Path, target: ScoopConfig, held: ScoopConfig, spec: dict[str, Any], info: dict[str, Any],
                seed: int | None = None, warm_start: bool = True) -> Any:
    """The run's model on its simulators (``target_envs`` in the target world, then ``held_envs`` in the held
    world), the actor's optimiser a :class:`HeldAdam`, the source actor copied in and, for DDPG with
    ``anchor_alpha`` > 0, the actor held near it (:class:`AnchoredDDPG`); with ``warm_start``, the source critic too."""
    settings = spec["adapt"]
    configs = [target] * settings["target_envs"] + [held] * settings["held_envs"]
    seed = info["seed"] if seed is None else seed
    env = make_mixed_vec_env(configs, seed, privileged_critic(spec), history_steps(spec))
    alpha = float(settings.get("anchor_alpha", 0.0))
    try:
        model = build_model(run_dir, env, spec, info, seed=seed,
                            algo_cls=AnchoredDDPG if alpha and info["algo"] == "ddpg" else None)
        actor = model.policy.actor
        actor.optimizer = HeldAdam(actor.parameters(), lr=model.lr_schedule(1.0),
                                   hold_steps=settings["critic_warmup_steps"], lr_scale=settings["actor_lr_scale"])
        # the starting actor, also when resuming (the checkpoint then replaces the weights): the anchor
        load_init_weights(model, Path(info["init_from"]), info["init_sha256"], trust=False)
        if isinstance(model, AnchoredDDPG):
            model.set_anchor(model.actor, alpha)
        if warm_start and info["adapt"]["critic_from"]:
            critic_into_sb3(info["adapt"]["critic_from"], model)
            if float(info["adapt"].get("length_scale", 1.0)) != 1.0:
                rescale_critics(model, float(info["adapt"]["length_scale"]), history_steps(spec))
    except BaseException:
        env.close()
        raise
    return model


def resume_adapt(run_dir: Path, progress: bool = True) -> Path:
    """Continue an interrupted adapt run from its last checkpoint (from its start when it has none)."""
    run_dir = Path(run_dir)
    read_run_json(run_dir)
    with lock_run_dir(run_dir):
        info = read_run_json(run_dir)
        refuse_run_of_other_machine(run_dir, info)
        if info.get("recipe") != ADAPT_RECIPE:
            raise ValueError(f"{run_dir} is not an adapt run; continue it with autoscoop train --resume {run_dir}")
        if info.get("status") == "finished":
            raise ValueError(f"{run_dir} already finished its {info['episodes']} episodes")
        spec = read_run_yaml(run_dir, "hyperparams.yaml")
        target = from_dict(read_run_yaml(run_dir, "config.yaml"))
        held = from_dict(read_run_yaml(run_dir, "held.yaml"))
        found = find_checkpoint(run_dir, info["algo"])
        if found is None:
            model = adapt_model(run_dir, target, held, spec, info)
            clear_run_outputs(run_dir)
            set_bookkeeping(info, wall_s=0.0, best_score=None, best_episode=None)
            write_run_json(run_dir, info)
            return train_model(run_dir, target, spec, info, done=0, model=model, progress=progress)
        checkpoint, state = found
        done = state["episodes_done"]
        model = adapt_model(run_dir, target, held, spec, info, seed=info["seed"] + done, warm_start=False)
        try:
            load_checkpoint(model, checkpoint, state)
            restore_to_checkpoint(run_dir, checkpoint, state)
        except ValueError:
            model.get_env().close()
            raise
        set_bookkeeping(info, state["wall_s"], state["best_score"], state["best_episode"])
        write_run_json(run_dir, info)
        return train_model(run_dir, target, spec, info, done=done, model=model, progress=progress,
                           evaluations_done=state["evaluations_done"])
