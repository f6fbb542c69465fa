"""What runs during training: the per-episode log (CSV, TensorBoard, noise decay, checkpoints, the stop at N)
and the periodic evaluation that keeps the best policy."""

from __future__ import annotations

import csv
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.utils import ConstantSchedule
from tqdm import tqdm

from autoscoop.agents.loading import SB3Policy
from autoscoop.core.config import ScoopConfig
from autoscoop.core.safe_files import atomic_output
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.training.checkpoints import actor_meta, save_checkpoint, save_safe_actor, write_run_json
from autoscoop.training.factories import set_noise_scale


def cycle_time_of(info: dict[str, Any]) -> float:
    """An episode's cycle time from its last ``info``: seconds from its start until success; NaN when it did not
    succeed (the environment times reaching the terminal point, loaded or not: an empty arrival is no cycle)."""
    if not info.get("success"):
        return math.nan
    cycle = float(info.get("cycle_time_s", math.nan))
    return cycle if math.isfinite(cycle) else math.nan


CSV_FIELDS = ["episode", "reward", "fill_factor", "cycle_time_s", "success", "steps", "spilled", "physics_error",
              "wall_s"]
"""The columns of ``episodes.csv``, one row per training episode (``cycle_time_s``: ``nan`` where it did not
succeed, :func:`cycle_time_of`)."""
EVALUATION_FIELDS = ["episode", "delivered_fill", "fill_factor", "success", "cycle_time_s"]
"""The columns of ``evaluations.csv``, one row per periodic evaluation."""


class EpisodeLogger(BaseCallback):
    """Counts episodes, writes the CSV and TensorBoard scalars, decays the noise, checkpoints, stops at N.

    Each checkpoint records the run's bookkeeping (episodes and evaluations done, wall time, best score)
    and rewrites ``run.json`` with it, so a run killed at any moment resumes with the right numbers.

    Args:
        run_dir: the run directory.
        episodes: stop after this many episodes in total.
        done: episodes already done (when resuming).
        info: the run's ``run.json`` (its ``wall_s``: seconds spent before, counted on; rewritten at checkpoints).
        spec: the algorithm's YAML (noise schedule).
        checkpoint_every: episodes between checkpoints.
        progress: show a progress bar.
        evaluator: the periodic evaluation, or ``None``.
        control_period_s: the environment's control period (an episode's steps from its elapsed time).
        evaluate_at_start: evaluate the starting policy before learning (fine-tuning: it is the bar).
        worlds: a curriculum's later worlds, by the episode after which each begins: the training
            environments and the periodic evaluation switch to it there, and the best policy is chosen
            again in it (a score in an easier world is no bar).
    """

    def __init__(self, run_dir: Path, episodes: int, done: int, info: dict[str, Any], spec: dict[str, Any],
                 checkpoint_every: int, progress: bool, evaluator: PolicyEvaluator | None = None,
                 control_period_s: float = 0.25, evaluate_at_start: bool = False,
                 worlds: dict[int, ScoopConfig] | None = None) -> None:
        super().__init__()
        self.worlds = dict(worlds or {})
        self.evaluate_at_start = evaluate_at_start
        self.control_period_s = control_period_s
        self.run_dir, self.episodes, self.done, self.info = run_dir, episodes, done, info
        self.evaluator = evaluator
        self.spec, self.checkpoint_every = spec, checkpoint_every
        self.returns: dict[int, float] = {}
        self.recent: list[dict[str, Any]] = []
        self.started = time.time() - float(info.get("wall_s", 0.0))  # the run's clock, across resumes
        self._checkpoint_due = False
        self.bar = tqdm(total=episodes, initial=done, desc="train", unit="ep", disable=not progress)
        self.csv_file = open(run_dir / "episodes.csv", "a", newline="")
        self.csv = csv.DictWriter(self.csv_file, fieldnames=CSV_FIELDS)
        if done == 0:
            self.csv.writeheader()

    def _on_training_start(self) -> None:
        self._update_noise()
        if self.evaluate_at_start and self.evaluator is not None:  # fine-tuning: the starting policy is the bar
            self.evaluator.evaluate(self.model, 0, self.logger)

    def _update_noise(self) -> None:
        """Set the exploration noise and, with ``learning_rate_end`` in the YAML, the learning rate for the
        episodes done: each falls linearly over the run, from its start (``noise.sigma_start``,
        ``hyperparams.learning_rate``) at episode 0 to its end (``noise.sigma_end``, ``learning_rate_end``)
        at the last episode; from the episode count, so a resumed run continues on the same line."""
        fraction = min(self.done / max(self.episodes, 1), 1.0)
        noise_spec = self.spec.get("noise")
        noise = getattr(self.model, "action_noise", None)
        if noise_spec and noise is not None:
            set_noise_scale(noise, noise_spec["sigma_start"] + fraction * (noise_spec["sigma_end"] - noise_spec["sigma_start"]))
        end = self.spec.get("learning_rate_end")
        if end is not None:
            start = float(self.spec["hyperparams"]["learning_rate"])
            self.model.lr_schedule = ConstantSchedule(start + fraction * (float(end) - start))

    def _on_step(self) -> bool:
        rewards, dones, infos = self.locals["rewards"], self.locals["dones"], self.locals["infos"]
        for i, (reward, done, info) in enumerate(zip(rewards, dones, infos)):
            self.returns[i] = self.returns.get(i, 0.0) + float(reward)
            if done:
                self.end_episode(i, info)
                if self.done >= self.episodes:
                    return False
        return True

    def end_episode(self, env_index: int, info: dict[str, Any]) -> None:
        """Log the episode environment ``env_index`` just ended (its last ``info``); evaluate, checkpoint when due."""
        self.done += 1
        row = {"episode": self.done, "reward": self.returns.pop(env_index, 0.0), "fill_factor": info["fill_factor"],
               "cycle_time_s": cycle_time_of(info), "success": int(info["success"]),
               "steps": int(round(info["elapsed_s"] / self.control_period_s)), "spilled": info["spilled"],
               "physics_error": int(info["physics_error"]), "wall_s": round(self.wall_s(), 2)}
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
        if self.done in self.worlds and self.done < self.episodes:
            self.enter_world(self.worlds[self.done])
        if self.done % self.checkpoint_every == 0 and self.done < self.episodes:
            self._checkpoint_due = True

    def enter_world(self, config: ScoopConfig) -> None:
        """A curriculum stage begins: evaluate in ``config``'s world from now, train in it from each environment's
        next reset (an environment has begun its next episode already when one ends: one episode later)."""
        self.model.get_env().env_method("set_randomize", config.randomize)
        if self.evaluator is not None:
            self.evaluator.enter_world(config)
        given = {key: value for key, value in config.randomize.to_dict().items() if value not in ([], "none")}
        print(f"curriculum: after episode {self.done}, randomize {given}", file=sys.stderr)

    def wall_s(self) -> float:
        """Seconds of wall time the run has taken: this process's part and the parts before a resume."""
        return time.time() - self.started

    def bookkeeping(self) -> dict[str, Any]:
        """What a checkpoint records of the run (:data:`autoscoop.training.checkpoints.BOOKKEEPING`)."""
        return {"episodes_done": self.done, "evaluations_done": self.evaluator.done if self.evaluator else 0,
                "wall_s": round(self.wall_s(), 3), "best_score": self.info.get("best_score"),
                "best_episode": self.info.get("best_episode")}

    def _on_rollout_end(self) -> None:
        # after the rollout's transitions are in the replay buffer (not yet in _on_step)
        if self._checkpoint_due:
            bookkeeping = self.bookkeeping()
            save_checkpoint(self.model, self.run_dir, bookkeeping, self.info["algo"])
            self.info["wall_s"] = round(bookkeeping["wall_s"], 1)
            write_run_json(self.run_dir, self.info)  # a kill from here on leaves run.json's numbers right
            self._checkpoint_due = False

    def _on_training_end(self) -> None:
        self.bar.close()
        self.csv_file.close()


@dataclass(frozen=True)
class Evaluation:
    """One periodic evaluation, as :class:`PolicyEvaluator` hands it to its observers: after its row of
    ``evaluations.csv``, the evaluated actor and (when it is the best so far) ``policy.*`` are written."""

    episode: int
    """training episodes done when it ran (0: the starting policy of a fine-tuning run)."""
    delivered_fill: float
    """its score, in [0, 1]: the mean over its episodes of the fill factor (capped at 1) of successes, 0 for failures."""
    fill_factor: float
    """mean fill factor over its episodes (mass in the bucket / rated load)."""
    success: float
    """fraction of its episodes that reached the terminal point loaded, in [0, 1]."""
    cycle_time_s: float
    """mean cycle time of its successful episodes (s); NaN when none succeeded."""
    best_score: float
    """the run's best delivered fill so far, this evaluation's included: the score of the kept ``policy.*``."""
    actor: Path | None
    """the evaluated actor (``evaluated/episode_NNNNN.safetensors``); ``None`` where the safe format cannot
    hold it (PPO)."""


EvaluationObserver = Callable[[Evaluation], None]
"""Called with each :class:`Evaluation` as training goes (``autoscoop sweep`` reports them to Ray Tune)."""


class PolicyEvaluator:
    """Evaluates the deterministic policy every ``every`` episodes and keeps the best as ``policy.*``.

    The score is the delivered fill: the fill factor of successful episodes (up to 1: mass above the
    rated load delivers no more, as the reward pays no more), zero for failures (what a loader is for). Seeds are fixed, so every evaluation sees the same piles. The kept policy
    is replaced only by a strictly better score (the best so far is ``info["best_score"]``, -1 before any).

    Args:
        done: evaluations already in ``evaluations.csv`` (when resuming).
        make_env: builds the evaluation environment from a config: the environment training steps
            (the model's observations; an asymmetric critic's carry privileged numbers).
        observers: called with each :class:`Evaluation`, in order, once its files are written.
        target_actor: evaluate, save and keep the model's target actor (the YAML's ``keep_target_actor``).
    """

    SEED = 10_000

    def __init__(self, run_dir: Path, config: ScoopConfig, every: int, episodes: int, info: dict[str, Any],
                 done: int = 0, make_env: Callable[[ScoopConfig], Any] = make_scoop_env,
                 observers: Sequence[EvaluationObserver] = (), target_actor: bool = False) -> None:
        self.run_dir, self.every, self.episodes, self.info, self.done = run_dir, every, episodes, info, done
        self.target_actor = target_actor
        self.observers = list(observers)
        self.make_env = make_env
        self.env = make_env(config)
        self.best = float(info.get("best_score", -1.0))
        path = run_dir / "evaluations.csv"
        self.csv_file = open(path, "a", newline="")
        self.csv = csv.DictWriter(self.csv_file, fieldnames=EVALUATION_FIELDS)
        if path.stat().st_size == 0:
            self.csv.writeheader()

    def enter_world(self, config: ScoopConfig) -> None:
        """Evaluate in ``config``'s world from now on; the next evaluation's policy is kept whatever its score."""
        self.env.close()
        self.env = self.make_env(config)
        self.best = -1.0
        self.info.pop("best_score", None)
        self.info.pop("best_episode", None)

    def evaluate(self, model: Any, episode: int, logger: Any) -> float:
        """Run the evaluation; save the policy if it is the best so far; return its score."""
        policy = SB3Policy(model, name="training", target=self.target_actor)
        results = [rollout(policy, self.env, self.SEED + i) for i in range(self.episodes)]
        fills = [r.fill_factor for r in results]
        successes = [r.success for r in results]
        cycles = [r.cycle_time_s for r in results if r.success]
        score = float(np.mean([r.delivered_fill for r in results]))
        row = {"episode": episode, "delivered_fill": round(score, 4), "fill_factor": round(float(np.mean(fills)), 4),
               "success": round(float(np.mean(successes)), 3),
               "cycle_time_s": round(float(np.mean(cycles)), 3) if cycles else math.nan}
        self.csv.writerow(row)
        self.csv_file.flush()
        self.done += 1
        logger.record("eval/delivered_fill", score)
        logger.record("eval/success", row["success"])
        # every evaluated actor stays (80 kB each): a policy judged on more episodes later can be picked
        meta = {**actor_meta(self.info, self.run_dir), "selected_at_episode": episode}
        actor = self.run_dir / "evaluated" / f"episode_{episode:05d}.safetensors"
        saved = save_safe_actor(model, actor, {**meta, "evaluation_delivered_fill": score}, target=self.target_actor)
        if score > self.best:
            self.best = score
            with atomic_output(self.run_dir / "policy.zip") as tmp:
                model.save(tmp)
            save_safe_actor(model, self.run_dir / "policy.safetensors", {**meta, "selection_score_delivered_fill": score},
                            target=self.target_actor)
            self.info.update(best_score=score, best_episode=episode)
        evaluation = Evaluation(episode=episode, delivered_fill=score, fill_factor=row["fill_factor"],
                                success=row["success"], cycle_time_s=row["cycle_time_s"], best_score=self.best,
                                actor=actor if saved else None)
        for observer in self.observers:
            observer(evaluation)
        return score

    def close(self) -> None:
        self.csv_file.close()
        self.env.close()
