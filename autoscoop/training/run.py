"""Train a scooping controller with Stable-Baselines3: config -> run directory.

A run directory holds everything needed to repeat and to use the run:

| file | what |
|---|---|
| run.json | algorithm, seed, episodes, package version, command, wall time, the policy zip's SHA-256 |
| config.yaml, hyperparams.yaml | the environment config and the algorithm's settings |
| episodes.csv | one row per training episode: reward, fill factor, cycle time, success, steps |
| tb/ | TensorBoard logs |
| checkpoint/ | every ``checkpoint_every`` episodes (for ``--resume``): the model's tensors (safetensors), replay buffer (npz), best policy so far and the run's bookkeeping (JSON); no pickle |
| evaluated/ | the actor (safetensors) at each periodic evaluation: ``episode_NNNNN.safetensors`` |
| policy.zip | the best SB3 model by periodic evaluation (pickle inside: load only what you trust) |
| policy.safetensors, policy.json | that policy's actor in the safe format, with its hash |
| last.safetensors, last.json | the actor at the end of training |
| critic.safetensors, critic.json | the critic(s) and target critic(s) at the end of training, with the recipe and config: what ``autoscoop adapt`` fine-tunes from (off-policy algorithms) |
| evaluations.csv | each periodic evaluation: episode, delivered fill, fill factor, success, cycle time |
| learning_curve.png | reward, fill factor and cycle time against episode (the paper's Fig. 8) |
| .lock, lock.json | the lock the writing process holds, and who that is (PID, host, start time) while it runs |

This module builds the run and drives it; :mod:`autoscoop.training.callbacks` writes the CSVs, the
evaluated actors and ``policy.*`` as training goes, :mod:`autoscoop.training.checkpoints` the checkpoints,
``run.json``, ``last.*`` and the lock: one process at a time writes a run directory (``train`` and
``resume`` hold its lock for the whole run; a second one is refused at once).
"""

from __future__ import annotations

import shutil
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Any

import torch
import yaml
from stable_baselines3 import DDPG, PPO, TD3

from autoscoop.agents.algorithms import ALGORITHMS
from autoscoop.agents.critic_files import has_critic, name_kept_actor, save_critic
from autoscoop.agents.demonstrations import add_scripted_demonstrations
from autoscoop.agents.policy_files import sha256_of
from autoscoop.core.config import ScoopConfig, from_dict, save_yaml
from autoscoop.core.safe_files import atomic_output, write_text_atomically
from autoscoop.core.version import __version__, dependency_versions
from autoscoop.training.callbacks import EpisodeLogger, Evaluation, PolicyEvaluator
from autoscoop.training.checkpoints import (
    CRITIC_FILE,
    actor_meta,
    clear_run_outputs,
    find_checkpoint,
    init_source,
    load_checkpoint,
    load_init_weights,
    lock_run_dir,
    read_run_json,
    read_run_yaml,
    refuse_run_of_other_machine,
    remove_checkpoints,
    restore_to_checkpoint,
    save_safe_actor,
    write_run_json,
)
from autoscoop.training.factories import (
    critics,
    history_steps,
    keep_target_actor,
    make_noise,
    make_policy,
    make_training_env,
    make_vec_env,
    repeated_pile_envs,
    replay_buffer_settings,
    time_limit_ends_return,
)
from autoscoop.training.hyper_ranges import check_training_settings
from autoscoop.training.learning_curve import plot_learning_curve
from autoscoop.training.recipes import DEFAULT_EPISODES, SHIPPED_RECIPE
from autoscoop.training.settings import config_at, curriculum_stages, load_recipe, with_hyper_overrides


@dataclass
class TrainArgs:
    """Arguments of one training run."""

    algo: str = "ddpg"
    """ddpg (the paper's), td3, sac, tqc or ppo; settings from autoscoop/training/hyperparams/ALGO.yaml."""
    episodes: int | None = None
    """training episodes; ``None``: the recipe's ``episodes`` (the paper's: 800)."""
    seed: int = 0
    """seed of the networks, the noise and the environments."""
    n_envs: int = 1
    """parallel simulators (in subprocesses when more than one)."""
    overrides: dict[str, Any] = field(default_factory=dict)
    """environment config overrides (dotted keys), applied after the algorithm's own."""
    out: Path | None = None
    """run directory; default runs/ALGO-sSEED-TIME."""
    checkpoint_every: int = 50
    """episodes between checkpoints of the model and the replay buffer."""
    eval_every: int = 50
    """episodes between evaluations of the deterministic policy; the best one is kept as policy.*."""
    eval_episodes: int = 10
    """episodes per evaluation (fixed seeds, the training config)."""
    progress: bool = True
    """show a progress bar."""
    init_from: Path | None = None
    """fine-tune: start from the policy of this finished run directory (same algorithm) instead of random weights."""
    trust: bool = False
    """fine-tune from ``init_from``'s ``policy.zip`` (the whole model; pickle, so only when trusted) rather than
    its safe actor file ``policy.safetensors``."""
    hyper: dict[str, str] = field(default_factory=dict)
    """overrides of the algorithm's YAML, ``{"noise.sigma_start": "0.05"}`` (see
    :func:`autoscoop.training.settings.with_hyper_overrides`)."""
    demo_episodes: int | None = None
    """scripted scoops put in the replay buffer before learning (off-policy algorithms only);
    ``None``: the recipe or the algorithm's YAML says (``demo_episodes``, 0 if absent)."""
    recipe: str = SHIPPED_RECIPE
    """a recipe of :data:`autoscoop.training.recipes.RECIPES`, laid over the algorithm's YAML
    (autoscoop/training/recipes/NAME.yaml); default the shipped policy's, ``paper`` for the paper's."""
    on_evaluation: Callable[[Evaluation], None] | None = None
    """called after each periodic evaluation, its files written (``autoscoop sweep`` reports it to Ray Tune);
    not recorded in the run directory."""
    command: str | None = None
    """the command ``run.json`` records; ``None``: this process's command line."""


def privileged_critic(spec: dict[str, Any]) -> bool:
    """Whether the YAML asks for an asymmetric critic (``privileged_critic: true``): the critic sees the
    simulator's privileged numbers (:mod:`autoscoop.envs.privileged`), the actor the robot's state."""
    return bool(spec.get("privileged_critic", False))


def _default_run_dir(args: TrainArgs) -> Path:
    return Path("runs") / f"{args.algo}-s{args.seed}-{time.strftime('%Y%m%d-%H%M%S')}"


def train(args: TrainArgs) -> Path:
    """Train from scratch into a new run directory; return it."""
    spec = with_hyper_overrides(load_recipe(args.algo, args.recipe), args.hyper)
    if args.episodes is None:
        args = replace(args, episodes=int(spec.get("episodes", DEFAULT_EPISODES)))
    demos = int(spec.get("demo_episodes", 0)) if args.demo_episodes is None else args.demo_episodes
    if demos and ALGORITHMS[args.algo] is PPO:
        raise ValueError("--demo-episodes needs an off-policy algorithm (ddpg, td3, sac); ppo has no replay buffer")
    if privileged_critic(spec) and (ALGORITHMS[args.algo] is PPO or spec.get("policy") != "paper"):
        raise ValueError("privileged_critic needs the paper's actor-critic (policy: paper) and ddpg, td3 or sac: "
                         "only its actor reads the state alone")
    if args.n_envs > 1 and not demos and ALGORITHMS[args.algo] is not PPO and not args.init_from:
        print(f"warning: --n-envs {args.n_envs} without scripted demonstrations: off-policy learners from random "
              "weights learned to scoop with two environments in 0 of 8 seeds (README, Speed); add "
              "--demo-episodes 20 or train with --n-envs 1", file=sys.stderr)
    end = spec.get("learning_rate_end")
    if end is not None and (isinstance(end, bool) or not isinstance(end, (int, float)) or not 0 < end <= 1
                            or "learning_rate" not in (spec.get("hyperparams") or {})):
        raise ValueError(f"learning_rate_end must be a number in (0, 1] beside hyperparams.learning_rate, got {end!r}")
    config = ScoopConfig().with_overrides({**(spec.get("env") or {}), **args.overrides})
    config_at(config, spec, args.episodes)  # a curriculum's stages are checked before anything starts
    check_training_settings(spec, args.n_envs)
    history_steps(spec)  # a bad history is refused before a run directory is made
    repeated_pile_envs(spec, args.n_envs)
    time_limit_ends_return(spec)
    keep_target_actor(spec)
    critics(spec)
    init_path = init_source(args.init_from, args.algo, args.trust) if args.init_from else None
    run_dir = Path(args.out) if args.out else _default_run_dir(args)
    created = not run_dir.exists()
    run_dir.mkdir(parents=True, exist_ok=True)
    try:
        with lock_run_dir(run_dir):  # first: a run being written is reported as such, with its process
            if (run_dir / "run.json").exists():
                raise ValueError(f"{run_dir} already holds a run; use --resume {run_dir} to continue it, "
                                 "or another --out")
            return _start(args, run_dir, config, spec, demos, init_path)
    except BaseException:
        if created and not (run_dir / "run.json").exists():  # it failed before it began: no run is left behind
            shutil.rmtree(run_dir, ignore_errors=True)
        raise


def _start(args: TrainArgs, run_dir: Path, config: ScoopConfig, spec: dict[str, Any], demos: int,
           init_path: Path | None) -> Path:
    """Build a new run's model, then write its files and train it (under the run directory's lock): a model
    that cannot be built (a setting torch refuses, an initial policy that does not fit) leaves no run."""
    info = {"algo": args.algo, "recipe": args.recipe, "seed": args.seed, "episodes": args.episodes,
            "n_envs": args.n_envs,
            "autoscoop_version": __version__, "command": args.command or " ".join(sys.argv),
            "torch": torch.__version__, "dependencies": dependency_versions(),
            "checkpoint_every": args.checkpoint_every, "eval_every": args.eval_every,
            "eval_episodes": args.eval_episodes, "demo_episodes": demos,
            "state_frame": "level" if config.sensor.level_with_imu else "chassis",
            "status": "running", "wall_s": 0.0}
    if init_path is not None:
        info.update(init_from=str(init_path.resolve()), init_sha256=sha256_of(init_path))
    model = _new_model(run_dir, config, spec, info, trust=args.trust)
    save_yaml(config, run_dir / "config.yaml")
    write_text_atomically(run_dir / "hyperparams.yaml", yaml.safe_dump(spec, sort_keys=False))
    write_run_json(run_dir, info)
    return train_model(run_dir, config, spec, info, done=0, model=model, progress=args.progress,
                on_evaluation=args.on_evaluation)


def resume(run_dir: Path, progress: bool = True, on_evaluation: Callable[[Evaluation], None] | None = None,
           trust: bool = False) -> Path:
    """Continue an interrupted run from its last checkpoint (episodes after it are redone; without a checkpoint
    the run starts again from episode 0). The resumed run's files are those an uninterrupted run writes.
    ``on_evaluation``: as :attr:`TrainArgs.on_evaluation`, for the evaluations from the checkpoint on.
    ``trust``: as :attr:`TrainArgs.trust`, for a run fine-tuned from a ``policy.zip`` that starts again from
    episode 0 and so loads the zip again (a checkpoint holds no pickle)."""
    run_dir = Path(run_dir)
    read_run_json(run_dir)  # a run directory, before a lock file is put in it
    with lock_run_dir(run_dir):
        return _continue(run_dir, progress, on_evaluation, trust)


def _continue(run_dir: Path, progress: bool, on_evaluation: Callable[[Evaluation], None] | None = None,
              trust: bool = False) -> Path:
    """:func:`resume` under the run directory's lock (``run.json`` is read again: the last holder may have
    finished the run)."""
    info = read_run_json(run_dir)
    refuse_run_of_other_machine(run_dir, info)
    if info.get("status") == "finished":
        raise ValueError(f"{run_dir} already finished its {info['episodes']} episodes")
    missing = [str(run_dir / name) for name in ("config.yaml", "hyperparams.yaml") if not (run_dir / name).is_file()]
    if missing:
        raise ValueError(f"cannot resume {run_dir}: missing {' and '.join(missing)} (a run directory holds "
                         "run.json, config.yaml and hyperparams.yaml)")
    spec = read_run_yaml(run_dir, "hyperparams.yaml")
    config = from_dict(read_run_yaml(run_dir, "config.yaml"))
    found = find_checkpoint(run_dir, info["algo"])
    if found is None:  # killed before its first checkpoint: start again, as if new
        model = _new_model(run_dir, config, spec, info, trust=trust)  # first: a refused --init zip changes no file
        clear_run_outputs(run_dir)
        set_bookkeeping(info, wall_s=0.0, best_score=None, best_episode=None)
        write_run_json(run_dir, info)
        return train_model(run_dir, config, spec, info, done=0, model=model, progress=progress, on_evaluation=on_evaluation)
    checkpoint, state = found
    done = state["episodes_done"]
    env = make_vec_env(config_at(config, spec, done), info["n_envs"], info["seed"] + done, privileged_critic(spec),
                       history_steps(spec), repeated_pile_envs(spec, info["n_envs"]))
    model = build_model(run_dir, env, spec, info, seed=info["seed"] + done)
    try:
        load_checkpoint(model, checkpoint, state)
        restore_to_checkpoint(run_dir, checkpoint, state)  # files last: a refused checkpoint changes none
    except ValueError:
        env.close()
        raise
    set_bookkeeping(info, state["wall_s"], state["best_score"], state["best_episode"])
    write_run_json(run_dir, info)
    return train_model(run_dir, config, spec, info, done=done, model=model, progress=progress,
                evaluations_done=state["evaluations_done"], on_evaluation=on_evaluation)


def set_bookkeeping(info: dict[str, Any], wall_s: float, best_score: float | None, best_episode: int | None) -> None:
    """Set ``run.json``'s wall time (s) and best evaluation to a checkpoint's (no best: the keys go, as in a new run)."""
    info["wall_s"] = wall_s
    info.pop("best_score", None)
    info.pop("best_episode", None)
    if best_score is not None:
        info.update(best_score=best_score, best_episode=best_episode)


def build_model(run_dir: Path, env: Any, spec: dict[str, Any], info: dict[str, Any], seed: int,
                algo_cls: type | None = None) -> Any:
    """The run's model, with fresh weights, on ``env``: the algorithm, networks, noise and settings of its YAML.
    ``algo_cls``: a subclass of the run's algorithm to build instead (fine-tuning's)."""
    policy, policy_kwargs = make_policy(info["algo"], spec)
    kwargs = dict(spec.get("hyperparams") or {})
    algo_cls = algo_cls or ALGORITHMS[info["algo"]]
    if issubclass(algo_cls, (DDPG, TD3)):
        kwargs["action_noise"] = make_noise(spec, info["n_envs"])
    if buffer_settings := replay_buffer_settings(spec):
        kwargs["replay_buffer_kwargs"] = buffer_settings
    return algo_cls(policy, env, seed=seed, device="cpu", tensorboard_log=str(run_dir / "tb"),
                    policy_kwargs=policy_kwargs or None, verbose=0, **kwargs)


def _new_model(run_dir: Path, config: ScoopConfig, spec: dict[str, Any], info: dict[str, Any],
               trust: bool = False) -> Any:
    """A fresh model on new environments: the initial run's weights when fine-tuning, demonstrations when asked."""
    env = make_vec_env(config, info["n_envs"], info["seed"], privileged_critic(spec), history_steps(spec),
                       repeated_pile_envs(spec, info["n_envs"]))
    try:
        model = build_model(run_dir, env, spec, info, seed=info["seed"])
        if info.get("init_from"):
            load_init_weights(model, Path(info["init_from"]), info["init_sha256"], trust)
        if info.get("demo_episodes"):
            added = add_scripted_demonstrations(model.replay_buffer, config, info["demo_episodes"],
                                                make_env=partial(make_training_env, privileged=privileged_critic(spec),
                                                                 history=history_steps(spec)),
                                                time_limit_ends_return=time_limit_ends_return(spec))
            print(f"replay buffer: {added} transitions of {info['demo_episodes']} scripted scoops", file=sys.stderr)
    except BaseException:
        env.close()
        raise
    return model


def train_model(run_dir: Path, config: ScoopConfig, spec: dict[str, Any], info: dict[str, Any], done: int,
                model: Any, progress: bool, evaluations_done: int = 0,
                on_evaluation: Callable[[Evaluation], None] | None = None) -> Path:
    """Train ``model`` (built on its environments) from episode ``done`` to ``info["episodes"]`` (``evaluations_done``
    evaluations already listed), evaluating in ``config``'s world and switching worlds at ``spec``'s curriculum, then
    write the final files: ``last.*``, ``policy.*`` when no evaluation ran, and ``critic.*`` (what
    :mod:`autoscoop.training.adapt` fine-tunes from). ``on_evaluation`` observes each periodic evaluation."""
    torch.set_num_threads(1)
    n_envs, episodes = info["n_envs"], info["episodes"]
    evaluator = PolicyEvaluator(run_dir, config_at(config, spec, done), info.get("eval_every", 50),
                                info.get("eval_episodes", 10), info, done=evaluations_done,
                                make_env=partial(make_training_env, privileged=privileged_critic(spec),
                                                 history=history_steps(spec)),
                                observers=[on_evaluation] if on_evaluation else (),
                                target_actor=keep_target_actor(spec)) if info.get("eval_every", 50) > 0 else None
    worlds = {episode: config_at(config, spec, episode) for episode, _ in curriculum_stages(spec) if episode > done}
    logger = EpisodeLogger(run_dir, episodes, done, info, spec, info["checkpoint_every"], progress, evaluator,
                           config.env.control_period_s, evaluate_at_start=bool(info.get("init_from")) and done == 0,
                           worlds=worlds)
    max_steps = config.max_episode_steps
    try:
        model.learn(total_timesteps=(episodes - done + n_envs) * max_steps, callback=logger,
                    reset_num_timesteps=done == 0, tb_log_name="run", progress_bar=False)
    finally:
        model.get_env().close()
        if evaluator is not None:
            evaluator.close()
        info["wall_s"] = round(logger.wall_s(), 1)
        write_run_json(run_dir, info)
    target = keep_target_actor(spec)
    save_safe_actor(model, run_dir / "last.safetensors", actor_meta(info, run_dir), target=target)
    if has_critic(model) and (run_dir / "last.safetensors").is_file():
        save_critic(model, run_dir / CRITIC_FILE, sha256_of(run_dir / "last.safetensors"),
                    {"spec": spec, "config": config.to_dict(), "run": run_dir.name,
                     "held_config": config_at(config, spec, episodes).to_dict()})
    if not (run_dir / "policy.zip").exists():  # no evaluation ran: the last policy is the policy
        with atomic_output(run_dir / "policy.zip") as tmp:
            model.save(tmp)
        save_safe_actor(model, run_dir / "policy.safetensors", actor_meta(info, run_dir), target=target)
    if (run_dir / CRITIC_FILE).is_file():  # the kept actor travels with its run's critic (NAME.critic.safetensors)
        name_kept_actor(run_dir / CRITIC_FILE, sha256_of(run_dir / "policy.safetensors"))
    info.update(status="finished", policy_zip_sha256=sha256_of(run_dir / "policy.zip"))
    write_run_json(run_dir, info)
    remove_checkpoints(run_dir)
    try:
        plot_learning_curve(run_dir / "episodes.csv", run_dir / "learning_curve.png")
    except ImportError:  # matplotlib missing: the CSV holds the same numbers
        pass
    return run_dir
