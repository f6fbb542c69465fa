"""What a training run is built from: the policy class, the exploration noise and the environments."""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial
from typing import Any

import numpy as np
from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise, VectorizedActionNoise
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

from autoscoop.agents import sb3_policies
from autoscoop.agents.networks import PAPER_LAYERS
from autoscoop.core.config import ScoopConfig
from autoscoop.core.state import ACTION_SIZE, checked_history_steps
from autoscoop.envs.history import ActorInputObservation
from autoscoop.envs.privileged import PrivilegedObservation
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.envs.shift import make_repeated_pile_env


def make_policy(algo: str, spec: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
    """The SB3 policy (class or name) and its keyword arguments for ``algo``.

    ``policy: paper`` in the algorithm's YAML gives the paper's networks (:mod:`autoscoop.agents.sb3_policies`;
    PPO: an MLP of the paper's layer sizes on the normalised state); anything else SB3's ``MlpPolicy``.
    """
    if spec.get("policy") != "paper":
        return "MlpPolicy", {}
    kwargs: dict[str, Any] = {"history_steps": history_steps(spec)} if history_steps(spec) > 1 else {}
    if (count := critics(spec)) is not None:
        kwargs["n_critics"] = count
    if algo in ("ddpg", "td3"):
        return sb3_policies.PaperPolicy, kwargs
    if algo == "sac":
        return sb3_policies.PaperSACPolicy, kwargs
    if algo == "tqc":
        return sb3_policies.PaperTQCPolicy, kwargs
    return "MlpPolicy", {"net_arch": {"pi": list(PAPER_LAYERS), "vf": list(PAPER_LAYERS)},
                         "features_extractor_class": sb3_policies.NormalizedState}


def history_steps(spec: dict[str, Any]) -> int:
    """The YAML's ``history_steps``: how many states (and commands) the actor reads (1 without the key).

    Raises:
        ValueError: a value that is not a whole number from 1 to :data:`~autoscoop.core.state.MAX_HISTORY_STEPS`.
    """
    return checked_history_steps(spec.get("history_steps", 1), "the recipe")


def critics(spec: dict[str, Any]) -> int | None:
    """The YAML's ``critics``: how many critics the run trains, each on the same transitions from its own start, so
    that one critic's overestimate does not carry into the targets. DDPG, TD3 and SAC (the paper's critics): each
    target takes the lowest of their estimates (clipped double Q); TQC (quantile critics): the targets pool their
    quantiles and drop the highest. ``None`` without the key: the algorithm's own number (DDPG 1, the others 2).

    Raises:
        ValueError: a value that is not a whole number from 1 to 10, or a key for PPO (no critic of this kind).
    """
    value = spec.get("critics")
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 10:
        raise ValueError(f"critics = {value!r} in the recipe is out of range; allowed whole numbers in [1, 10]")
    if spec.get("algo") == "ppo":
        raise ValueError("critics needs an off-policy algorithm (ddpg, td3, sac, tqc); this run trains 'ppo'")
    return value


def time_limit_ends_return(spec: dict[str, Any]) -> bool:
    """The YAML's ``time_limit_ends_return`` (false without the key): a scoop cut off by the time limit is stored
    in the replay buffer as ended, so the critic's return stops there instead of being carried on by its own
    estimate of the next state. Only for a privileged critic, which reads the time used: to a critic that knows
    the clock, the time limit is part of the task, and a scoop short of the terminal point when it runs out
    has lost the bonus.

    Raises:
        ValueError: a value that is not true or false, or true without ``privileged_critic``.
    """
    value = spec.get("time_limit_ends_return", False)
    if not isinstance(value, bool):
        raise ValueError(f"time_limit_ends_return = {value!r} in the recipe must be true or false")
    if value and not spec.get("privileged_critic", False):
        raise ValueError("time_limit_ends_return needs privileged_critic: true (only that critic reads the time used)")
    return value


def keep_target_actor(spec: dict[str, Any]) -> bool:
    """The YAML's ``keep_target_actor`` (false without the key): the run evaluates, keeps and exports DDPG's or
    TD3's target actor, the Polyak average of the actor's weights (each gradient step moves it ``tau`` of the way,
    so it averages the last few hundred updates), instead of the actor it trails.

    Raises:
        ValueError: a value that is not true or false, or true for an algorithm without a target actor.
    """
    value = spec.get("keep_target_actor", False)
    if not isinstance(value, bool):
        raise ValueError(f"keep_target_actor = {value!r} in the recipe must be true or false")
    if value and spec.get("algo") not in ("ddpg", "td3"):
        raise ValueError(f"keep_target_actor needs ddpg or td3 (a target actor); this run trains {spec.get('algo')!r}")
    return value


def replay_buffer_settings(spec: dict[str, Any]) -> dict[str, Any]:
    """The keyword arguments of the off-policy learner's replay buffer (SB3's ``replay_buffer_kwargs``) that the
    YAML asks for: ``handle_timeout_termination`` off with ``time_limit_ends_return``, nothing otherwise."""
    return {"handle_timeout_termination": False} if time_limit_ends_return(spec) else {}


def repeated_pile_envs(spec: dict[str, Any], n_envs: int) -> int:
    """The YAML's ``repeated_pile_envs``: how many of the ``n_envs`` simulators train on a shift's pile scooped
    again and again (:class:`autoscoop.envs.shift.RepeatedPileEnv`) instead of the run's world (0 without the key).

    Raises:
        ValueError: a value that is not a whole number from 0 to ``n_envs``.
    """
    value = spec.get("repeated_pile_envs", 0)
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= n_envs:
        raise ValueError(f"repeated_pile_envs = {value!r} in the recipe is out of range; allowed whole numbers in "
                         f"[0, {n_envs}] (--n-envs {n_envs})")
    return value


def make_noise(spec: dict[str, Any], n_envs: int) -> Any:
    """The exploration noise the YAML's ``noise`` section names, at ``sigma_start``; ``None`` without one."""
    noise_spec = spec.get("noise")
    if not noise_spec:
        return None
    mean, sigma = np.zeros(ACTION_SIZE), np.full(ACTION_SIZE, noise_spec["sigma_start"])
    if noise_spec["type"] == "ornstein_uhlenbeck":
        base = OrnsteinUhlenbeckActionNoise(mean, sigma, theta=noise_spec.get("theta", 0.15), dt=1.0)
    else:
        base = NormalActionNoise(mean, sigma)
    return VectorizedActionNoise(base, n_envs) if n_envs > 1 else base


def set_noise_scale(noise: Any, sigma: float) -> None:
    """Set the exploration noise's standard deviation (all environments)."""
    for part in getattr(noise, "noises", [noise]):
        if part is not None:
            part._sigma = np.full(ACTION_SIZE, sigma)


def make_training_env(config: ScoopConfig, privileged: bool = False, history: int = 1,
                      repeated_pile: bool = False) -> Any:
    """One environment as training steps it: with ``history`` > 1 (the YAML's ``history_steps``) its
    observations are the actor's input of that many states and commands (:mod:`autoscoop.envs.history`);
    with ``privileged`` (the YAML's ``privileged_critic``) they carry the simulator's privileged numbers after
    it (:mod:`autoscoop.envs.privileged`) for the critic, while the actor reads its input only. With
    ``repeated_pile`` it scoops a shift's pile again and again (:func:`autoscoop.envs.shift.make_repeated_pile_env`)
    in ``config``'s world without its randomisation."""
    env = make_repeated_pile_env(config) if repeated_pile else make_scoop_env(config)
    if history > 1:
        env = ActorInputObservation(env, history)
    return PrivilegedObservation(env) if privileged else env


def make_vec_env(config: ScoopConfig, n_envs: int, seed: int, privileged: bool = False, history: int = 1,
                 repeated_pile: int = 0) -> Any:
    """``n_envs`` training environments (:func:`make_training_env`; in subprocesses when more than one),
    seeded from ``seed``; the last ``repeated_pile`` of them on a shift's pile scooped again and again."""
    return _vectorised([partial(make_training_env, config, privileged, history, index >= n_envs - repeated_pile)
                        for index in range(n_envs)], seed)


def make_mixed_vec_env(configs: Sequence[ScoopConfig], seed: int, privileged: bool = False, history: int = 1) -> Any:
    """One training environment per config, each in its own world (fine-tuning mixes a target world with the
    worlds a policy already holds); in subprocesses when more than one, seeded from ``seed``."""
    return _vectorised([partial(make_training_env, config, privileged, history) for config in configs], seed)


def _vectorised(factories: list[Any], seed: int) -> Any:
    vec = SubprocVecEnv(factories, start_method="fork") if len(factories) > 1 else DummyVecEnv(factories)
    vec.seed(seed)
    return vec
