"""Speed of the simulator: raw physics steps, environment steps and real-time factor, on one core.

All three come from the same run: the scripted baseline scoops the default pile; the physics
steps are timed inside the environment's step (a substep observer), the environment steps around it
(from the controller's action to the step's end), and the real-time factor is simulated episode time
over wall time, resets and the controller included. Every new
pile variant is settled once before timing starts (that cost is paid once per environment), and
the measurement is repeated; the median is reported beside every repeat, since a shared virtual
machine's speed varies from minute to minute.

With several environments (``autoscoop bench --n-envs N``, :func:`run_vec_bench`) it measures instead the
aggregate environment steps per second of N environments stepped together, built as training builds them
(SB3's ``SubprocVecEnv``), against one (``DummyVecEnv``), and their ratio: whether more simulators make
training's data come faster on this machine. Random or fixed actions, a fixed number of steps.
"""

from __future__ import annotations

import math
import os
import platform
import statistics
import time
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np
from tqdm import tqdm

from autoscoop.agents.loading import heuristic_for
from autoscoop.core.config import ScoopConfig
from autoscoop.core.policy import Policy
from autoscoop.core.version import __version__
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env


def pin_to_one_core() -> tuple[str, set[int] | None]:
    """Restrict this process to a single CPU core where the OS allows it.

    Returns:
        What was done, and the previous set of cores (to restore), or ``None``.
    """
    if hasattr(os, "sched_setaffinity"):
        previous = os.sched_getaffinity(0)
        core = min(previous)
        os.sched_setaffinity(0, {core})
        return f"pinned to core {core}", previous
    return "not pinned (no sched_setaffinity on this OS)", None


def cpu_description() -> str:
    """The processor's model name (from ``/proc/cpuinfo`` on Linux), else what ``platform`` knows.

    Speeds from different machines are only comparable when it is known which machine gave them.
    """
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("model name"):
                    return line.partition(":")[2].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


class _TimedPolicy:
    """The controller, noting when each of its actions goes to the environment (the env step's start)."""

    def __init__(self, policy: Policy) -> None:
        self.policy = policy
        self.name = policy.name
        self.handed_over = 0.0

    def reset(self) -> None:
        self.policy.reset()

    def act(self, observation: np.ndarray) -> np.ndarray:
        action = self.policy.act(observation)
        self.handed_over = time.perf_counter()
        return action


def measure_once(config: ScoopConfig, episodes: int, seed: int, env: Any = None) -> dict[str, float]:
    """One timed pass of ``episodes`` scripted episodes.

    Physics steps are timed by a substep observer, from one physics step's end to the next within an
    environment step (so the simulator runs its steps one by one, as it does with the torque mass
    source's load cell attached); environment steps from the controller's action to the step's end.
    """
    env = env or make_scoop_env(config)
    sim = env.unwrapped.sim
    policy = _TimedPolicy(heuristic_for(config))
    clock: dict[str, Any] = {"physics_time": 0.0, "physics_steps": 0, "env_time": 0.0, "env_steps": 0, "last": None,
                             "elapsed_s": 0.0}

    def after_physics_step() -> None:
        now = time.perf_counter()
        if clock["last"] is not None:  # the first step of an env step follows the env's own work: not timed
            clock["physics_time"] += now - clock["last"]
            clock["physics_steps"] += 1
        clock["last"] = now

    def after_env_step(step: int, obs: np.ndarray, action: np.ndarray, reward: float, info: dict) -> None:
        clock["env_time"] += time.perf_counter() - policy.handed_over
        clock["env_steps"] += 1
        clock["last"] = None
        clock["elapsed_s"] = info["elapsed_s"]

    simulated = 0.0
    sim.add_substep_observer(after_physics_step)
    wall_start = time.perf_counter()
    try:
        for i in range(episodes):
            rollout(policy, env, seed + i, observers=(after_env_step,))
            simulated += clock["elapsed_s"]
    finally:
        sim.remove_substep_observer(after_physics_step)
    wall = time.perf_counter() - wall_start
    timed = clock["physics_steps"] > 0  # none when an env step is a single physics step
    return {"physics_steps_per_s": clock["physics_steps"] / clock["physics_time"] if timed else math.nan,
            "env_steps_per_s": clock["env_steps"] / clock["env_time"],
            "realtime_factor": simulated / wall, "simulated_s": simulated, "wall_s": wall}


def run_bench(config: ScoopConfig | None = None, episodes: int = 10, repeats: int = 3, seed: int = 0,
              progress: bool = True) -> dict[str, Any]:
    """Measure ``repeats`` times on one core; report the medians and every repeat."""
    config = config or ScoopConfig()
    pinned, previous_cores = pin_to_one_core()
    try:
        env = make_scoop_env(config)
        for variant_seed in tqdm(range(config.pile.variants), desc="settling piles", disable=not progress):
            env.reset(seed=variant_seed)
        runs = [measure_once(config, episodes, seed, env)
                for _ in tqdm(range(repeats), desc="bench", disable=not progress)]
        env.close()
    finally:
        if previous_cores is not None:
            os.sched_setaffinity(0, previous_cores)
    median = {key: statistics.median(run[key] for run in runs)
              for key in ("physics_steps_per_s", "env_steps_per_s", "realtime_factor")}
    return {
        **median,
        "repeats": runs,
        "episodes_per_repeat": episodes,
        "timestep_s": config.env.timestep_s,
        "n_particles": config.pile.n_particles,
        "cpu": cpu_description(),
        "cpu_count": os.cpu_count(),
        "mujoco_version": mujoco.__version__,
        "python_version": platform.python_version(),
        "cores": pinned,
        "autoscoop_version": __version__,
        "config": config.to_dict(),
    }


MakeVecEnv = Callable[[ScoopConfig, int, int], Any]
"""Builds ``n_envs`` environments seeded from ``seed``: ``make_vec(config, n_envs, seed)``, an SB3 ``VecEnv``.
The commands pass training's :func:`autoscoop.training.factories.make_vec_env` (evaluation may not import
training), so the bench steps the environments exactly as training builds them."""


def _vec_actions(action_space: Any, n_envs: int, steps: int, actions: str, seed: int) -> np.ndarray:
    """The ``steps`` × ``n_envs`` actions a vector-env measurement sends, drawn before the clock starts.

    ``random``: uniform over the action space (seeded, the same for every measurement of one seed);
    ``fixed``: the middle of the action space (all zeros for the scoop's normalised [-1, 1] actions).
    """
    low, high = action_space.low, action_space.high
    if actions == "fixed":
        return np.broadcast_to((low + high) / 2.0, (steps, n_envs, *action_space.shape)).astype(action_space.dtype)
    if actions != "random":
        raise ValueError(f"actions must be 'random' or 'fixed', not {actions!r}")
    rng = np.random.default_rng(seed)
    return rng.uniform(low, high, size=(steps, n_envs, *action_space.shape)).astype(action_space.dtype)


def measure_vec_env(vec: Any, steps: int, seed: int = 0, actions: str = "random") -> dict[str, float]:
    """Aggregate environment steps per second of the vector environment ``vec``'s environments stepped together.

    ``vec`` is built as training builds it (:data:`MakeVecEnv`: SB3's ``SubprocVecEnv`` for more than one
    environment, ``DummyVecEnv`` for one). Each environment takes ``steps`` steps (episodes end and reset
    inside, as in training); the wall time covers the ``steps`` vector steps from the first action to the
    last step's end, after a reset with ``seed``; drawing the actions is not timed.

    Returns:
        ``env_steps_per_s``: all environments' steps per wall second; ``per_env_steps_per_s``: that over
        ``n_envs``; ``env_steps``: the steps taken (``n_envs × steps``); ``wall_s``: seconds.
    """
    plan = _vec_actions(vec.action_space, vec.num_envs, steps, actions, seed)
    vec.seed(seed)
    vec.reset()
    start = time.perf_counter()
    for step_actions in plan:
        vec.step(step_actions)
    wall = time.perf_counter() - start
    total = vec.num_envs * steps
    return {"env_steps_per_s": total / wall, "per_env_steps_per_s": total / wall / vec.num_envs,
            "env_steps": total, "wall_s": wall}


def settled_vec_env(make_vec: MakeVecEnv, config: ScoopConfig, n_envs: int, seed: int, progress: bool = True) -> Any:
    """The training vector environment with every pile variant settled once in each environment.

    Settling a new variant costs seconds and is paid once per environment (each subprocess has its own
    bank), so it is done before any timing, in every environment at once.
    """
    vec = make_vec(config, n_envs, seed)
    for variant_seed in tqdm(range(config.pile.variants), desc=f"settling piles ({n_envs} envs)",
                             disable=not progress):
        vec.env_method("reset", seed=variant_seed)
    return vec


def run_vec_bench(make_vec: MakeVecEnv, config: ScoopConfig | None = None, n_envs: int = 2, steps: int = 2000,
                  repeats: int = 3, seed: int = 0, actions: str = "random", progress: bool = True) -> dict[str, Any]:
    """Aggregate env steps/s with one environment and with ``n_envs`` together, and their ratio.

    The two are measured alternately, ``repeats`` times each (one environment first in every repeat), on
    environments built and settled once; nothing is pinned to a core. The reported rates are the medians,
    and ``scaling_ratio`` is their quotient (``n_envs``'s aggregate over one's; 1 for ``n_envs`` = 1);
    every repeat is kept with its own ratio.
    """
    config = config or ScoopConfig()
    if n_envs < 1 or steps < 1 or repeats < 1:
        raise ValueError(f"n_envs, steps and repeats must be 1 or more (got {n_envs}, {steps}, {repeats})")
    counts = [1] if n_envs == 1 else [1, n_envs]
    envs: dict[int, Any] = {}
    runs: list[dict[str, Any]] = []
    try:
        for count in counts:
            envs[count] = settled_vec_env(make_vec, config, count, seed, progress)
        for _ in tqdm(range(repeats), desc="bench vec", disable=not progress):
            repeat: dict[str, Any] = {f"n{count}": measure_vec_env(envs[count], steps, seed, actions)
                                      for count in counts}
            repeat["scaling_ratio"] = repeat[f"n{n_envs}"]["env_steps_per_s"] / repeat["n1"]["env_steps_per_s"]
            runs.append(repeat)
    finally:
        for vec in envs.values():
            vec.close()
    rate_1 = statistics.median(run["n1"]["env_steps_per_s"] for run in runs)
    rate_n = statistics.median(run[f"n{n_envs}"]["env_steps_per_s"] for run in runs)
    return {
        "n_envs": n_envs,
        "vec_env": "SubprocVecEnv (fork)" if n_envs > 1 else "DummyVecEnv",
        "env_steps_per_s_1": rate_1,
        "env_steps_per_s_n": rate_n,
        "per_env_steps_per_s_n": rate_n / n_envs,
        "scaling_ratio": rate_n / rate_1,
        "repeats": runs,
        "steps_per_env": steps,
        "actions": actions,
        "seed": seed,
        "timestep_s": config.env.timestep_s,
        "control_period_s": config.env.control_period_s,
        "n_particles": config.pile.n_particles,
        "cpu": cpu_description(),
        "cpu_count": os.cpu_count(),
        "usable_cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "mujoco_version": mujoco.__version__,
        "python_version": platform.python_version(),
        "autoscoop_version": __version__,
        "config": config.to_dict(),
    }
