"""Speed of the simulator: raw physics steps, environment steps and real-time factor, on one core.

All three come from the same run: the scripted baseline scoops the default pile; the physics
steps are timed inside the environment's step (a substep observer), the environment steps around it
(from the controller's action to the step's end), and the real-time factor is simulated episode time
over wall time, resets and the controller included. Every new
pile variant is settled once before timing starts (that cost is paid once per environment), and
the measurement is repeated; the median is reported beside every repeat, since a shared virtual
machine's speed varies from minute to minute.
"""

from __future__ import annotations

import math
import os
import platform
import statistics
import time
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
