"""Speed of the simulator: raw physics steps, environment steps and real-time factor, on one core.

All three come from the same run: the scripted baseline scoops the default pile; the physics
steps are timed inside the environment's step, the environment steps around it, and the real-time
factor is simulated episode time over wall time, resets and the controller included. Every new
pile variant is settled once before timing starts (that cost is paid once per environment), and
the measurement is repeated; the median is reported beside every repeat, since a shared virtual
machine's speed varies from minute to minute.
"""

from __future__ import annotations

import os
import platform
import statistics
import time
from typing import Any

import mujoco
from tqdm import tqdm

from autoscoop.core.version import __version__
from autoscoop.agents.loading import heuristic_for
from autoscoop.core.config import ScoopConfig
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


def measure_once(config: ScoopConfig, episodes: int, seed: int, env: Any = None) -> dict[str, float]:
    """One timed pass of ``episodes`` scripted episodes."""
    env = env or make_scoop_env(config)
    sim = env.unwrapped.sim
    policy = heuristic_for(config)
    physics_time, physics_steps = 0.0, 0
    original_step = sim.step

    def timed_step(n_steps: int) -> None:
        nonlocal physics_time, physics_steps
        start = time.perf_counter()
        original_step(n_steps)
        physics_time += time.perf_counter() - start
        physics_steps += n_steps

    sim.step = timed_step
    env_time, env_steps, simulated = 0.0, 0, 0.0
    wall_start = time.perf_counter()
    try:
        for i in range(episodes):
            obs, _ = env.reset(seed=seed + i)
            policy.reset()
            while True:
                action = policy.act(obs)
                start = time.perf_counter()
                obs, _, terminated, truncated, info = env.step(action)
                env_time += time.perf_counter() - start
                env_steps += 1
                if terminated or truncated:
                    break
            simulated += info["elapsed_s"]
    finally:
        sim.step = original_step
    wall = time.perf_counter() - wall_start
    return {"physics_steps_per_s": physics_steps / physics_time, "env_steps_per_s": env_steps / env_time,
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
