"""Train a scooping controller with Stable-Baselines3: config -> run directory.

A run directory holds everything needed to repeat and to use the run:

| file | what |
|---|---|
| run.json | algorithm, seed, episodes, package version, command, wall time, the policy zip's SHA-256 |
| config.yaml, hyperparams.yaml | the environment config and the algorithm's settings |
| episodes.csv | one row per training episode: reward, fill factor, cycle time, success, steps |
| tb/ | TensorBoard logs |
| checkpoint/ | model and replay buffer every ``checkpoint_every`` episodes (for ``--resume``) |
| evaluated/ | the actor (safetensors) at each periodic evaluation: ``episode_NNNNN.safetensors`` |
| policy.zip | the best SB3 model by periodic evaluation (pickle inside: load only what you trust) |
| policy.safetensors, policy.json | that policy's actor in the safe format, with its hash |
| last.safetensors, last.json | the actor at the end of training |
| evaluations.csv | each periodic evaluation: episode, delivered fill, fill factor, success, cycle time |
| learning_curve.png | reward, fill factor and cycle time against episode (the paper's Fig. 8) |
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import sys
import time
from dataclasses import dataclass, field
from functools import partial
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import torch
import yaml
from stable_baselines3 import DDPG, PPO, TD3
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise, VectorizedActionNoise
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv
from tqdm import tqdm

from autoscoop.core.version import __version__
from autoscoop.agents.algorithms import ALGORITHMS
from autoscoop.agents.demonstrations import add_scripted_demonstrations
from autoscoop.agents.policy_files import PolicyFileError, actor_from_sb3, save_actor, sha256_of
from autoscoop.core.config import ScoopConfig, from_dict, save_yaml
from autoscoop.envs.scoop import make_scoop_env

CSV_FIELDS = ["episode", "reward", "fill_factor", "cycle_time_s", "success", "steps", "spilled", "physics_error",
              "wall_s"]


@dataclass
class TrainArgs:
    """Arguments of one training run."""

    algo: str = "ddpg"
    """ddpg (the paper's), td3, sac or ppo; settings from autoscoop/training/hyperparams/ALGO.yaml."""
    episodes: int = 800
    """training episodes (the paper: 800)."""
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
    """allow ``init_from`` to name a run whose ``run.json`` does not vouch for its ``policy.zip`` (pickle)."""
    hyper: dict[str, str] = field(default_factory=dict)
    """overrides of the algorithm's YAML, ``{"noise.sigma_start": "0.05"}`` (see :func:`with_hyper_overrides`)."""
    demo_episodes: int | None = None
    """scripted scoops put in the replay buffer before learning (off-policy algorithms only);
    ``None``: the algorithm's YAML says (``demo_episodes``, 0 if absent)."""


def load_hyperparams(algo: str) -> dict[str, Any]:
    """The algorithm's YAML from the package (``autoscoop/training/hyperparams/ALGO.yaml``)."""
    if algo not in ALGORITHMS:
        raise ValueError(f"--algo {algo!r} is not offered; choose one of {sorted(ALGORITHMS)}")
    text = (resources.files("autoscoop") / "training" / "hyperparams" / f"{algo}.yaml").read_text()
    return yaml.safe_load(text)


def with_hyper_overrides(spec: dict[str, Any], overrides: dict[str, str]) -> dict[str, Any]:
    """The algorithm's settings with ``section.key=value`` overrides (``hyperparams.learning_rate=3e-4``,
    ``noise.sigma_start=0.05``); only keys the YAML already has, values parsed as YAML scalars of the same type.

    Raises:
        ValueError: an unknown key, or a value of another type than the YAML's.
    """
    out = {name: dict(section) if isinstance(section, dict) else section for name, section in spec.items()}
    for dotted, text in overrides.items():
        section, _, key = dotted.partition(".")
        if not isinstance(out.get(section), dict) or key not in out[section]:
            known = sorted(f"{name}.{k}" for name, sec in out.items() if isinstance(sec, dict) for k in sec)
            raise ValueError(f"--hyper {dotted}: not a setting of this algorithm; known: {', '.join(known)}")
        old = out[section][key]
        value = yaml.safe_load(text)
        if isinstance(old, float) and not isinstance(value, bool):
            try:  # YAML reads 3e-4 as a string
                value = float(text)
            except ValueError:
                pass
        if type(value) is not type(old):
            raise ValueError(f"--hyper {dotted}={text}: expected a {type(old).__name__} like {old!r}")
        out[section][key] = value
    return out


def _make_policy(algo: str, spec: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
    if spec.get("policy") != "paper":
        return "MlpPolicy", {}
    from autoscoop.agents import sb3_policies  # noqa: PLC0415

    if algo in ("ddpg", "td3"):
        return sb3_policies.PaperPolicy, {}
    if algo == "sac":
        return sb3_policies.PaperSACPolicy, {}
    return "MlpPolicy", {"net_arch": {"pi": [100, 80, 60], "vf": [100, 80, 60]},
                         "features_extractor_class": sb3_policies.NormalizedState}


def _make_noise(spec: dict[str, Any], n_envs: int) -> Any:
    noise_spec = spec.get("noise")
    if not noise_spec:
        return None
    mean, sigma = np.zeros(3), np.full(3, noise_spec["sigma_start"])
    if noise_spec["type"] == "ornstein_uhlenbeck":
        base = OrnsteinUhlenbeckActionNoise(mean, sigma, theta=noise_spec.get("theta", 0.15), dt=1.0)
    else:
        base = NormalActionNoise(mean, sigma)
    return VectorizedActionNoise(base, n_envs) if n_envs > 1 else base


def set_noise_scale(noise: Any, sigma: float) -> None:
    """Set the exploration noise's standard deviation (all environments)."""
    for part in getattr(noise, "noises", [noise]):
        if part is not None:
            part._sigma = np.full(3, sigma)


def _make_vec_env(config: ScoopConfig, n_envs: int, seed: int) -> Any:
    factories = [partial(make_scoop_env, config) for _ in range(n_envs)]
    vec = SubprocVecEnv(factories, start_method="fork") if n_envs > 1 else DummyVecEnv(factories)
    vec.seed(seed)
    return vec


class EpisodeLogger(BaseCallback):
    """Counts episodes, writes the CSV and TensorBoard scalars, decays the noise, checkpoints, stops at N.

    Args:
        run_dir: the run directory.
        episodes: stop after this many episodes in total.
        done: episodes already done (when resuming).
        spec: the algorithm's YAML (noise schedule).
        checkpoint_every: episodes between checkpoints.
        progress: show a progress bar.
    """

    def __init__(self, run_dir: Path, episodes: int, done: int, spec: dict[str, Any], checkpoint_every: int,
                 progress: bool, evaluator: "PolicyEvaluator | None" = None, control_period_s: float = 0.25,
                 evaluate_at_start: bool = False) -> None:
        super().__init__()
        self.evaluate_at_start = evaluate_at_start
        self.control_period_s = control_period_s
        self.run_dir, self.episodes, self.done = run_dir, episodes, done
        self.evaluator = evaluator
        self.spec, self.checkpoint_every = spec, checkpoint_every
        self.returns: dict[int, float] = {}
        self.recent: list[dict[str, Any]] = []
        self.started = time.time()
        self._checkpoint_due = False
        self.bar = tqdm(total=episodes, initial=done, desc="train", unit="ep", disable=not progress)
        self.csv_file = open(run_dir / "episodes.csv", "a", newline="")  # noqa: SIM115
        self.csv = csv.DictWriter(self.csv_file, fieldnames=CSV_FIELDS)
        if done == 0:
            self.csv.writeheader()

    def _on_training_start(self) -> None:
        self._update_noise()
        if self.evaluate_at_start and self.evaluator is not None:  # fine-tuning: the starting policy is the bar
            self.evaluator.evaluate(self.model, 0, self.logger)

    def _update_noise(self) -> None:
        noise_spec = self.spec.get("noise")
        noise = getattr(self.model, "action_noise", None)
        if noise_spec and noise is not None:
            fraction = min(self.done / max(self.episodes, 1), 1.0)
            set_noise_scale(noise, noise_spec["sigma_start"] + fraction * (noise_spec["sigma_end"] - noise_spec["sigma_start"]))

    def _on_step(self) -> bool:
        rewards, dones, infos = self.locals["rewards"], self.locals["dones"], self.locals["infos"]
        for i, (reward, done, info) in enumerate(zip(rewards, dones, infos)):
            self.returns[i] = self.returns.get(i, 0.0) + float(reward)
            if done:
                self._end_episode(i, info)
                if self.done >= self.episodes:
                    return False
        return True

    def _end_episode(self, env_index: int, info: dict[str, Any]) -> None:
        self.done += 1
        row = {"episode": self.done, "reward": self.returns.pop(env_index, 0.0), "fill_factor": info["fill_factor"],
               "cycle_time_s": info.get("cycle_time_s", math.nan), "success": int(info["success"]),
               "steps": int(round(info["elapsed_s"] / self.control_period_s)), "spilled": info["spilled"],
               "physics_error": int(info["physics_error"]), "wall_s": round(time.time() - self.started, 2)}
        self.csv.writerow(row)
        self.csv_file.flush()
        self.recent = (self.recent + [row])[-20:]
        successes = [r for r in self.recent if r["success"]]
        self.logger.record("scoop/fill_factor", row["fill_factor"])
        self.logger.record("scoop/success", row["success"])
        self.logger.record("scoop/episode_reward", row["reward"])
        if row["success"]:
            self.logger.record("scoop/cycle_time_s", row["cycle_time_s"])
        self.bar.update(1)
        self.bar.set_postfix(fill=f"{np.mean([r['fill_factor'] for r in self.recent]):.2f}",
                             cycle=f"{np.mean([r['cycle_time_s'] for r in successes]):.1f}" if successes else "-",
                             success=f"{len(successes) / len(self.recent):.2f}")
        self._update_noise()
        if self.evaluator is not None and (self.done % self.evaluator.every == 0 or self.done == self.episodes):
            self.evaluator.evaluate(self.model, self.done, self.logger)
        if self.done % self.checkpoint_every == 0 and self.done < self.episodes:
            self._checkpoint_due = True

    def _on_rollout_end(self) -> None:
        # after the rollout's transitions are in the replay buffer (not yet in _on_step)
        if self._checkpoint_due:
            save_checkpoint(self.model, self.run_dir, self.done)
            self._checkpoint_due = False

    def _on_training_end(self) -> None:
        self.bar.close()
        self.csv_file.close()


class PolicyEvaluator:
    """Evaluates the deterministic policy every ``every`` episodes and keeps the best as ``policy.*``.

    The score is the delivered fill: the fill factor of successful episodes, zero for failures
    (what a loader is for). Seeds are fixed, so every evaluation sees the same piles.
    """

    SEED = 10_000

    def __init__(self, run_dir: Path, config: ScoopConfig, every: int, episodes: int, info: dict[str, Any]) -> None:
        self.run_dir, self.every, self.episodes, self.info = run_dir, every, episodes, info
        self.env = make_scoop_env(config)
        self.best = float(info.get("best_score", -1.0))
        path = run_dir / "evaluations.csv"
        self.csv_file = open(path, "a", newline="")  # noqa: SIM115
        self.csv = csv.DictWriter(self.csv_file, fieldnames=["episode", "delivered_fill", "fill_factor", "success",
                                                              "cycle_time_s"])
        if path.stat().st_size == 0:
            self.csv.writeheader()

    def evaluate(self, model: Any, episode: int, logger: Any) -> float:
        """Run the evaluation; save the policy if it is the best so far; return its score."""
        from autoscoop.agents.loading import SB3Policy  # noqa: PLC0415 - loading imports this module lazily
        from autoscoop.evaluation.evaluate import run_episode  # noqa: PLC0415

        policy = SB3Policy(model, name="training")
        results = [run_episode(self.env, policy, self.SEED + i) for i in range(self.episodes)]
        fills = [r.fill_factor for r in results]
        successes = [r.success for r in results]
        cycles = [r.cycle_time_s for r in results if r.success]
        score = float(np.mean([f if s else 0.0 for f, s in zip(fills, successes)]))
        row = {"episode": episode, "delivered_fill": round(score, 4), "fill_factor": round(float(np.mean(fills)), 4),
               "success": round(float(np.mean(successes)), 3),
               "cycle_time_s": round(float(np.mean(cycles)), 3) if cycles else math.nan}
        self.csv.writerow(row)
        self.csv_file.flush()
        logger.record("eval/delivered_fill", score)
        logger.record("eval/success", row["success"])
        # every evaluated actor stays (80 kB each): a policy judged on more episodes later can be picked
        meta = {**_actor_meta(self.info, self.run_dir), "selected_at_episode": episode}
        save_safe_actor(model, self.run_dir / "evaluated" / f"episode_{episode:05d}.safetensors",
                        {**meta, "evaluation_delivered_fill": score})
        if score > self.best:
            self.best = score
            model.save(self.run_dir / "policy.zip")
            save_safe_actor(model, self.run_dir / "policy.safetensors", {**meta, "selection_score_delivered_fill": score})
            self.info.update(best_score=score, best_episode=episode)
        return score

    def close(self) -> None:
        self.csv_file.close()
        self.env.close()


def save_safe_actor(model: Any, path: Path, metadata: dict[str, Any]) -> bool:
    """Write the model's actor in the safe format; ``False`` (nothing written) where that format cannot hold it.

    The safe format holds the paper's deterministic actor (DDPG, TD3, SAC's mean); PPO's Gaussian
    policy is kept in ``policy.zip`` only, which its run directory vouches for.
    """
    try:
        actor = actor_from_sb3(model)
    except PolicyFileError:
        return False
    save_actor(actor, path, metadata)
    return True


def _actor_meta(info: dict[str, Any], run_dir: Path) -> dict[str, Any]:
    return {"algo": info["algo"], "seed": info["seed"], "episodes": info["episodes"],
            "autoscoop_version": __version__, "run": run_dir.name}


def save_checkpoint(model: Any, run_dir: Path, episodes_done: int) -> None:
    """Write model, replay buffer and progress to ``checkpoint/``, atomically (a crash keeps the last one)."""
    tmp = run_dir / "checkpoint.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    model.save(tmp / "model.zip")
    if hasattr(model, "save_replay_buffer"):
        model.save_replay_buffer(tmp / "replay_buffer.pkl")
    (tmp / "state.json").write_text(json.dumps({"episodes_done": episodes_done,
                                                "num_timesteps": int(model.num_timesteps),
                                                "model_sha256": sha256_of(tmp / "model.zip")}))
    final = run_dir / "checkpoint"
    old = run_dir / "checkpoint.old"
    shutil.rmtree(old, ignore_errors=True)
    if final.exists():
        final.rename(old)
    tmp.rename(final)
    shutil.rmtree(old, ignore_errors=True)


def _truncate_csv(path: Path, episodes: int) -> None:
    """Keep the header and the first ``episodes`` rows (what the checkpoint had seen)."""
    if not path.exists():
        return
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:1 + episodes]))


def init_model_zip(run_dir: Path, algo: str, trust: bool) -> Path:
    """The SB3 zip of a finished run to fine-tune from, after checking that it may be loaded.

    Raises:
        ValueError: not a run directory, another algorithm, or a zip the run does not vouch for
            (its ``run.json`` records the SHA-256) and ``trust`` is false.
    """
    from autoscoop.agents.loading import zip_is_vouched_for  # noqa: PLC0415

    run_dir = Path(run_dir)
    zip_path = run_dir / "policy.zip"
    if not (run_dir / "run.json").is_file() or not zip_path.is_file():
        raise ValueError(f"--init {run_dir}: not a training run directory (needs run.json and policy.zip)")
    source_algo = json.loads((run_dir / "run.json").read_text()).get("algo")
    if source_algo != algo:
        raise ValueError(f"--init {run_dir}: that run trained {source_algo!r}, this one trains {algo!r}")
    if not trust and not zip_is_vouched_for(zip_path):
        raise ValueError(f"--init {run_dir}: its run.json does not vouch for policy.zip (SHA-256), and loading "
                         "a zip runs pickle; pass --trust if you trust where it came from")
    return zip_path


def _drop_evaluations_after(path: Path, episodes: int) -> None:
    """Keep the header and the evaluations made at or before ``episodes`` (what the checkpoint had seen)."""
    if not path.exists():
        return
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:1] + [line for line in lines[1:] if int(line.split(",", 1)[0]) <= episodes]))


def _default_run_dir(args: TrainArgs) -> Path:
    return Path("runs") / f"{args.algo}-s{args.seed}-{time.strftime('%Y%m%d-%H%M%S')}"


def train(args: TrainArgs) -> Path:
    """Train from scratch into a new run directory; return it."""
    spec = with_hyper_overrides(load_hyperparams(args.algo), args.hyper)
    demos = int(spec.get("demo_episodes", 0)) if args.demo_episodes is None else args.demo_episodes
    if demos and ALGORITHMS[args.algo] is PPO:
        raise ValueError("--demo-episodes needs an off-policy algorithm (ddpg, td3, sac); ppo has no replay buffer")
    config = ScoopConfig().with_overrides({**(spec.get("env") or {}), **args.overrides})
    init_zip = init_model_zip(args.init_from, args.algo, args.trust) if args.init_from else None
    run_dir = Path(args.out) if args.out else _default_run_dir(args)
    if (run_dir / "run.json").exists():
        raise ValueError(f"{run_dir} already holds a run; use --resume {run_dir} to continue it, or another --out")
    run_dir.mkdir(parents=True, exist_ok=True)
    save_yaml(config, run_dir / "config.yaml")
    (run_dir / "hyperparams.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    info = {"algo": args.algo, "seed": args.seed, "episodes": args.episodes, "n_envs": args.n_envs,
            "autoscoop_version": __version__, "command": " ".join(sys.argv), "torch": torch.__version__,
            "checkpoint_every": args.checkpoint_every, "eval_every": args.eval_every,
            "eval_episodes": args.eval_episodes, "demo_episodes": demos,
            "status": "running", "wall_s": 0.0}
    if init_zip is not None:
        info.update(init_from=str(init_zip.resolve()), init_sha256=sha256_of(init_zip))
    _write_run_json(run_dir, info)
    return _run(run_dir, config, spec, info, done=0, model=None, progress=args.progress)


def resume(run_dir: Path, progress: bool = True) -> Path:
    """Continue an interrupted run from its last checkpoint (episodes after it are redone)."""
    run_dir = Path(run_dir)
    info_path = run_dir / "run.json"
    if not info_path.exists():
        raise ValueError(f"{run_dir} is not a run directory (no run.json)")
    info = json.loads(info_path.read_text())
    if info.get("status") == "finished":
        raise ValueError(f"{run_dir} already finished its {info['episodes']} episodes")
    spec = yaml.safe_load((run_dir / "hyperparams.yaml").read_text())
    config = from_dict(yaml.safe_load((run_dir / "config.yaml").read_text()))
    checkpoint = run_dir / "checkpoint"
    if not (checkpoint / "state.json").exists():
        shutil.rmtree(checkpoint, ignore_errors=True)
        (run_dir / "episodes.csv").unlink(missing_ok=True)
        return _run(run_dir, config, spec, info, done=0, model=None, progress=progress)
    state = json.loads((checkpoint / "state.json").read_text())
    if sha256_of(checkpoint / "model.zip") != state["model_sha256"]:
        raise ValueError(f"{checkpoint / 'model.zip'} does not match its recorded hash; refusing to load it")
    _truncate_csv(run_dir / "episodes.csv", state["episodes_done"])
    _drop_evaluations_after(run_dir / "evaluations.csv", state["episodes_done"])  # they are run again
    env = _make_vec_env(config, info["n_envs"], info["seed"] + state["episodes_done"])
    algo_cls = ALGORITHMS[info["algo"]]
    model = algo_cls.load(checkpoint / "model.zip", env=env, device="cpu")
    if (checkpoint / "replay_buffer.pkl").exists() and hasattr(model, "load_replay_buffer"):
        model.load_replay_buffer(checkpoint / "replay_buffer.pkl")
    if model.action_noise is None and spec.get("noise"):
        model.action_noise = _make_noise(spec, info["n_envs"])
    return _run(run_dir, config, spec, info, done=state["episodes_done"], model=model, progress=progress)


def _load_init_weights(model: Any, zip_path: Path, sha256: str) -> None:
    """Copy the networks (actor, critic and their targets) of a vetted SB3 zip into ``model``."""
    if sha256_of(zip_path) != sha256:
        raise ValueError(f"{zip_path} changed since this run started from it (SHA-256); refusing to load it")
    source = type(model).load(zip_path, device="cpu")
    model.policy.load_state_dict(source.policy.state_dict())


def _write_run_json(run_dir: Path, info: dict[str, Any]) -> None:
    tmp = run_dir / "run.json.tmp"
    tmp.write_text(json.dumps(info, indent=2) + "\n")
    os.replace(tmp, run_dir / "run.json")


def _run(run_dir: Path, config: ScoopConfig, spec: dict[str, Any], info: dict[str, Any], done: int,
         model: Any, progress: bool) -> Path:
    torch.set_num_threads(1)
    n_envs, seed, episodes = info["n_envs"], info["seed"], info["episodes"]
    if model is None:
        env = _make_vec_env(config, n_envs, seed)
        policy, policy_kwargs = _make_policy(info["algo"], spec)
        kwargs = dict(spec.get("hyperparams") or {})
        algo_cls = ALGORITHMS[info["algo"]]
        if algo_cls in (DDPG, TD3):
            kwargs["action_noise"] = _make_noise(spec, n_envs)
        model = algo_cls(policy, env, seed=seed, device="cpu", tensorboard_log=str(run_dir / "tb"),
                         policy_kwargs=policy_kwargs or None, verbose=0, **kwargs)
        if info.get("init_from"):
            _load_init_weights(model, Path(info["init_from"]), info["init_sha256"])
        if info.get("demo_episodes"):
            added = add_scripted_demonstrations(model.replay_buffer, config, info["demo_episodes"])
            print(f"replay buffer: {added} transitions of {info['demo_episodes']} scripted scoops", file=sys.stderr)
    else:
        model.tensorboard_log = str(run_dir / "tb")
    started = time.time()
    evaluator = PolicyEvaluator(run_dir, config, info.get("eval_every", 50), info.get("eval_episodes", 10), info) \
        if info.get("eval_every", 50) > 0 else None
    logger = EpisodeLogger(run_dir, episodes, done, spec, info["checkpoint_every"], progress, evaluator,
                           config.env.control_period_s, evaluate_at_start=bool(info.get("init_from")) and done == 0)
    max_steps = config.max_episode_steps
    try:
        model.learn(total_timesteps=(episodes - done + n_envs) * max_steps, callback=logger,
                    reset_num_timesteps=done == 0, tb_log_name="run", progress_bar=False)
    finally:
        model.get_env().close()
        if evaluator is not None:
            evaluator.close()
        info["wall_s"] = round(info.get("wall_s", 0.0) + time.time() - started, 1)
        _write_run_json(run_dir, info)
    save_safe_actor(model, run_dir / "last.safetensors", _actor_meta(info, run_dir))
    if not (run_dir / "policy.zip").exists():  # no evaluation ran: the last policy is the policy
        model.save(run_dir / "policy.zip")
        save_safe_actor(model, run_dir / "policy.safetensors", _actor_meta(info, run_dir))
    info.update(status="finished", policy_zip_sha256=sha256_of(run_dir / "policy.zip"))
    _write_run_json(run_dir, info)
    shutil.rmtree(run_dir / "checkpoint", ignore_errors=True)
    try:
        from autoscoop.training.learning_curve import plot_learning_curve  # noqa: PLC0415

        plot_learning_curve(run_dir / "episodes.csv", run_dir / "learning_curve.png")
    except ImportError:  # matplotlib missing: the CSV holds the same numbers
        pass
    return run_dir

