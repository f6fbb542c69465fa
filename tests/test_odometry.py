"""The odometry speed: the wheels' mean speed over ``sensor.odometry_window_steps`` physics steps.

The wheels' velocity servos ring at the physics step while they push into the pile; a window of
one step (the instantaneous wheel speed, the reading of the first versions) then reads a speed
that depends on the step a reading lands on, so a sensor delay of an odd number of steps read
another speed than an even one. Two steps average the ringing out.
"""

from __future__ import annotations

import numpy as np
import pytest

from autoscoop.core.config import ConfigError, ScoopConfig
from autoscoop.envs.scoop import ScoopEnv
from autoscoop.sim.scene import WHEEL_RADIUS_M, WHEELS

SMALL = {"pile.variants": 2}


def pushing_run(window: int, delay_steps: int = 0, periods: int = 16) -> tuple[ScoopEnv, list[float], list[float]]:
    """Drive in at full speed with the arm lowered and the edge tipped fully down (seed 0; the wheels
    then push the bucket along the ground and ring) for ``periods`` control periods; the state's v per
    period, and the instantaneous mean wheel speed x radius of every physics step (an observer)."""
    config = ScoopConfig().with_overrides({**SMALL, "sensor.odometry_window_steps": window,
                                          "sensor.delay_s": delay_steps * ScoopConfig().env.timestep_s})
    env = ScoopEnv(config)
    obs, _ = env.reset(seed=0)
    sim = env.sim
    wheels = [sim.model.joint(w).dofadr[0] for w in WHEELS]
    instantaneous: list[float] = []
    sim.add_substep_observer(lambda: instantaneous.append(float(sim.data.qvel[wheels].mean() * WHEEL_RADIUS_M)))
    speeds = []
    for _ in range(periods):
        obs, _, terminated, truncated, _ = env.step(np.ones(3, dtype=np.float32))
        speeds.append(float(obs[6]))
        if terminated or truncated:
            break
    return env, speeds, instantaneous


def test_window_of_one_step_is_the_instantaneous_wheel_speed():
    env, _, instantaneous = pushing_run(window=1, periods=4)
    assert env.sim.odometry_speed_mps == pytest.approx(instantaneous[-1], abs=1e-12)


@pytest.mark.parametrize("window", [2, 5])
def test_the_reading_is_the_mean_over_the_window(window):
    env, _, instantaneous = pushing_run(window=window, periods=6)
    assert env.sim.odometry_speed_mps == pytest.approx(np.mean(instantaneous[-window:]), abs=1e-9)


def test_the_window_starts_afresh_at_reset():
    env, _, _ = pushing_run(window=2, periods=6)
    env.reset(seed=1)
    assert env.sim.odometry_speed_mps == pytest.approx(0.0, abs=1e-3)  # at rest: no speed from the last episode


def test_two_steps_average_out_the_ringing_a_delay_of_one_step_lands_on():
    """While the wheels push the bucket along, a reading one step late differs from one two steps late
    by the ringing with a one-step window, hardly at all with two steps."""
    def spread(window: int) -> float:
        _, even, _ = pushing_run(window, delay_steps=2)
        _, odd, _ = pushing_run(window, delay_steps=1)
        n = min(len(even), len(odd))
        return float(np.max(np.abs(np.subtract(even[:n], odd[:n]))))

    assert spread(1) > 0.15
    assert spread(2) < 0.06


def test_the_window_is_checked():
    with pytest.raises(ConfigError, match="sensor.odometry_window_steps"):
        ScoopConfig().with_overrides({"sensor.odometry_window_steps": 0})
