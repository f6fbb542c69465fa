"""A scripted three-phase scoop: approach, fill, exit. It uses only the 12-number state.

1. approach: drive in at full speed with the bucket low and level until the tip meets the pile;
2. fill: push on into the pile with the bucket level, then keep driving in while raising the arm
   and curling the bucket a little each step;
3. exit: curl fully, lift the tip to the terminal height and back off until the tip is over the
   terminal point (the tip's position along the ground is dead-reckoned from wheel odometry and
   the arm's kinematics since the tip met the pile; odometry over-reads while the wheels push
   into the pile, which ``push_slip_fraction`` corrects).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from autoscoop.core import kinematics
from autoscoop.core.config import RewardConfig
from autoscoop.core.machine import MachineError
from autoscoop.core.state import CommandLimits, advance_targets


@dataclass(frozen=True)
class HeuristicParams:
    """Thresholds and rates of the scripted scoop (angles in rad, distances in m, times in s)."""

    contact_gap_m: float = 0.02
    """approach ends when the tip is this close to the pile (or once anything is in the bucket)."""
    penetrate_steps: int = 8
    """control steps of driving into the pile with the bucket level before curling."""
    penetrate_tilt_rad: float = 0.05
    """tilt held while penetrating (positive tips the cutting edge down)."""
    fill_lift_step_rad: float = 0.01
    """lift target change per control step while filling (raising is negative)."""
    fill_curl_step_rad: float = 0.1
    """tilt target change per control step while filling (curling is negative)."""
    fill_speed_fraction: float = 0.95
    """drive speed while filling, as a fraction of the limit."""
    fill_steps: int = 5
    """control steps spent filling."""
    push_slip_fraction: float = 0.2
    """share of the wheel odometry that is slip while pushing into the pile (dead reckoning; 0.35 for the
    instantaneous odometry of ``sensor.odometry_window_steps=1``, which under-reads there)."""
    exit_tilt_rad: float = -0.5
    """tilt held on the way out (fully curled)."""
    exit_height_margin_m: float = 0.03
    """aim the tip this much above the terminal point (the arm sags under load)."""
    terminal_dx_m: float = RewardConfig().terminal_dx_m
    """terminal point x from the pile's toe."""
    terminal_z_m: float = RewardConfig().terminal_z_m
    """terminal point height."""
    control_period_s: float = 0.25
    limits: CommandLimits = field(default_factory=CommandLimits)


def machine_params(**given: object) -> HeuristicParams:
    """The scripted scoop's parameters for the machine this process runs: the defaults, then the machine's
    ``scripted_scoop`` section, then ``given``.

    Raises:
        MachineError: the machine's section names a parameter that does not exist.
    """
    tuned = dict(kinematics.MACHINE.scripted_scoop)
    known = {f.name for f in fields(HeuristicParams)} - {"limits", "terminal_dx_m", "terminal_z_m", "control_period_s"}
    unknown = sorted(set(tuned) - known)
    if unknown:
        raise MachineError(f"machine {kinematics.MACHINE.name}: scripted_scoop.{unknown[0]}: not a parameter of the "
                           f"scripted scoop; known: {', '.join(sorted(known))}")
    return HeuristicParams(**{**tuned, **given})


def lift_for_tip_height(tip_z_m: float, tilt_rad: float) -> float:
    """The lift angle that puts the tip at ``tip_z_m`` for a given tilt (clipped to the lift range)."""
    lifts = np.linspace(*kinematics.LIFT_RANGE_RAD, 401)
    heights = kinematics.arm_pose(lifts, np.full_like(lifts, tilt_rad)).tip[:, 1]
    return float(lifts[np.argmin(np.abs(heights - tip_z_m))])


class HeuristicScooper:
    """The scripted baseline controller; see the module docstring.

    Args:
        params: its thresholds and rates.
    """

    name = "heuristic"

    def __init__(self, params: HeuristicParams | None = None) -> None:
        self.params = params or machine_params()
        self._exit_lift = lift_for_tip_height(self.params.terminal_z_m + self.params.exit_height_margin_m,
                                              self.params.exit_tilt_rad)
        self.reset()

    def reset(self) -> None:
        self.phase = "approach"
        self._targets: np.ndarray | None = None
        self._fill_steps = 0
        self._tip_world_x = 0.0
        self._last_tip_chassis_x = 0.0
        self._last_speed = 0.0

    def act(self, observation: np.ndarray) -> np.ndarray:
        p = self.params
        obs = np.asarray(observation, dtype=np.float64)
        tip_x, pile_distance, speed, lift, tilt = obs[1], obs[5], obs[6], obs[7], obs[8]
        if self._targets is None:
            self._targets = np.array([0.0, lift, tilt])
        else:
            # dead reckoning of the tip along the ground: chassis motion + arm motion; the wheels slip
            # while they push the bucket into the pile, so odometry over-reads there
            travel = 0.5 * (speed + self._last_speed) * p.control_period_s
            if self.phase in ("penetrate", "fill") and travel > 0:
                travel *= 1.0 - p.push_slip_fraction
            self._tip_world_x += travel + (tip_x - self._last_tip_chassis_x)
        self._last_tip_chassis_x, self._last_speed = tip_x, speed

        desired = self._targets.copy()
        # the pile is reached when the tip is close to it, or when material already rides in the bucket
        # (a sharp edge slides under the first particles before the gap closes)
        if self.phase == "approach" and (pile_distance <= p.contact_gap_m or obs[0] > 0.0):
            self.phase, self._tip_world_x = "penetrate", -pile_distance
        if self.phase == "penetrate" and self._fill_steps >= p.penetrate_steps:
            self.phase, self._fill_steps = "fill", 0
        if self.phase == "fill" and self._fill_steps >= p.fill_steps:
            self.phase = "exit"
        if self.phase == "approach":
            desired[0] = p.limits.max_speed_mps
        elif self.phase == "penetrate":
            self._fill_steps += 1
            desired[0] = p.limits.max_speed_mps
            desired[2] = p.penetrate_tilt_rad
        elif self.phase == "fill":
            self._fill_steps += 1
            desired[0] = p.fill_speed_fraction * p.limits.max_speed_mps
            desired[1] = self._targets[1] - p.fill_lift_step_rad
            desired[2] = self._targets[2] - p.fill_curl_step_rad
        else:
            desired[1], desired[2] = self._exit_lift, p.exit_tilt_rad
            remaining = self._tip_world_x - p.terminal_dx_m
            desired[0] = -np.clip(remaining / p.control_period_s, 0.0, p.limits.max_speed_mps)
        span = p.limits.high - p.limits.low
        action = np.clip((desired - self._targets) / span, -1.0, 1.0)
        self._targets = advance_targets(self._targets, action, p.limits)
        return action.astype(np.float32)
