"""The one rollout loop: run a controller for one episode and return its :class:`EpisodeOutcome`.

Evaluation, the recorder, the speed benchmark, scripted demonstrations, training's periodic
evaluations, the tools and the benchmarks all run episodes through :func:`rollout`; whatever they
need per step they get from an observer, not from a loop of their own.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from autoscoop.core.policy import Policy, state_frame_of
from autoscoop.envs.outcome import EpisodeOutcome

StepObserver = Callable[[int, np.ndarray, np.ndarray, float, dict], None]
"""Called after each step with (step index, observation before the step, action, reward, info)."""

TransitionObserver = Callable[[int, np.ndarray, np.ndarray, float, np.ndarray, bool, bool, dict], None]
"""Called after each step with the whole transition: (step index, observation before the step, action,
reward, observation after the step, terminated, truncated, info); for replay buffers, which need the
last step's next observation and whether the episode ended or was cut off."""


def rollout(policy: Policy, env: Any, seed: int, observers: Iterable[StepObserver] = (),
            options: dict[str, Any] | None = None, *,
            transition_observers: Iterable[TransitionObserver] = (),
            stop: Callable[[], bool] | None = None) -> EpisodeOutcome:
    """Run one episode of ``policy`` in ``env`` from ``seed``.

    Args:
        policy: the controller; reset before the episode. Where it declares a ``state_frame`` (a policy
            file), the environment builds the state in that frame (``sensor.level_with_imu``).
        env: a Gymnasium environment of autoscoop (``make_scoop_env``), possibly wrapped (a recorder).
        seed: the episode's seed (``env.reset(seed=seed)``).
        observers: called after every step, in order (see :data:`StepObserver`).
        options: passed to ``env.reset``.
        transition_observers: called after every step, after ``observers``, in order (see
            :data:`TransitionObserver`).
        stop: asked after every step, after the observers: ``True`` ends the episode there (a person
            driving by hand pressed Enter or closed the window); default: only the environment ends it.

    Returns:
        The episode's outcome, from the last step's ``info``.
    """
    observers = tuple(observers)
    transition_observers = tuple(transition_observers)
    frame = state_frame_of(policy)
    if frame is not None:  # a policy file's frame (sensor.level_with_imu) is the one its actor was trained on
        env.unwrapped.use_state_frame(frame)
    obs, info = env.reset(seed=seed, options=options)
    policy.reset()
    total, steps = 0.0, 0
    while True:
        action = np.asarray(policy.act(obs))
        next_obs, reward, terminated, truncated, info = env.step(action)
        for observer in observers:
            observer(steps, obs, action, float(reward), info)
        for transition_observer in transition_observers:
            transition_observer(steps, obs, action, float(reward), next_obs, bool(terminated), bool(truncated), info)
        obs = next_obs
        total += float(reward)
        steps += 1
        if terminated or truncated or (stop is not None and stop()):
            break
    return EpisodeOutcome.from_info(info, seed=seed, steps=steps, episode_return=total)
