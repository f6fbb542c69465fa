"""The scripted rest of a loading cycle after the scoop: back out, drive to the hopper, dump, back off, return.

A small state machine on the robot's own readings: the 12-number state (odometry speed, lift and tilt
angles) and two ranges measured along the loader's path from the bucket's cutting edge (the tip), one to
the hopper's centre and one to the pile's toe. It commands the same three targets as a scoop policy
(forward speed, lift, tilt) through the same actions in [-1, 1] and the same limits
(:func:`autoscoop.core.state.advance_targets`). Every phase has a time limit; a phase that reaches it
ends there and the next one starts (the cycle records which).

I-cycle loading: the loader drives straight back and forth; once its arm is up and its front is clear of the
hopper's spot, the hopper is spotted between it and the pile, under the raised bucket (a truck backing in), and
it leaves sideways after the dump:

========  ==========================================================  ============================================
phase     commands                                                    ends when
========  ==========================================================  ============================================
back_out  full speed back, arm up, bucket curled                      arm up, the loader's front clear of the spot
to_hopper toward the hopper's centre (either way), slowing near it    tip over the hopper's centre
dump      stand, bucket tipped down fully                             tipped, then held ``dump_hold_s``
back_off  stand, bucket curled again                                  curled (the hopper then leaves)
return    forward to the pile, slowing, arm down, bucket level        ``start_gap_m`` short of the toe, at rest
========  ==========================================================  ============================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from autoscoop.core import kinematics
from autoscoop.core.state import CommandLimits, advance_targets

PHASES = ("back_out", "to_hopper", "dump", "back_off", "return", "done")
"""The script's phases in order; ``done`` ends the cycle."""
HOPPER_PHASES = ("to_hopper", "dump", "back_off")
"""Phases during which the hopper stands at its spot (it is spotted as ``to_hopper`` begins, leaves after
``back_off``)."""
STATE_TIP_X, STATE_SPEED, STATE_LIFT, STATE_TILT = 1, 6, 7, 8
"""Indices of the tip's x ahead of the chassis centre (m), odometry speed (m/s), lift angle (rad) and tilt angle
(rad) in the 12-number state."""
LOADER_FRONT_M = math.ceil(100 * (kinematics.MACHINE.wheels.axle_x_m[1] + kinematics.MACHINE.wheels.radius_m)) / 100
"""How far the loader's body reaches ahead of the chassis centre below its arm: the front wheels' front (front
axle + wheel radius, the machine's) rounded up to the centimetre, m."""


@dataclass(frozen=True)
class Ranges:
    """Distances along the loader's path (world x) from the bucket tip, m; positive ahead of the tip.

    Attributes:
        to_hopper_m: to the hopper's centre (its spot, whether or not the hopper stands there yet).
        to_pile_m: to the pile's toe.
    """

    to_hopper_m: float
    to_pile_m: float


@dataclass(frozen=True)
class ScriptParams:
    """Poses, tolerances and limits of the scripted phases (angles rad, distances m, times s)."""

    hopper_half_length_m: float
    """half the hopper's inner length along the path, m."""
    start_gap_m: float
    """the return ends with the tip this far short of the pile's toe, m."""
    start_lift_rad: float
    """lift angle the return ends with (the scoop's start pose), rad."""
    start_tilt_rad: float
    """tilt angle the return ends with, rad."""
    phase_limit_s: float
    """longest time of any phase, s."""
    control_period_s: float = 0.25
    hopper_wall_m: float = 0.02
    """thickness of the hopper's walls, m."""
    clearance_m: float = 0.05
    """the loader's front stays this far behind the hopper's outer near wall when it is spotted, m."""
    carry_lift_rad: float = kinematics.LIFT_RANGE_RAD[0]
    """lift angle while carrying (the arm fully up), rad."""
    carry_tilt_rad: float = kinematics.TILT_RANGE_RAD[0]
    """tilt angle while carrying (the bucket fully curled), rad."""
    dump_tilt_rad: float = kinematics.TILT_RANGE_RAD[1]
    """tilt angle to dump (the cutting edge fully down), rad."""
    dump_hold_s: float = 1.5
    """time the bucket is held tipped over the hopper, s."""
    position_tolerance_m: float = 0.02
    """a range within this of its aim counts as reached, m."""
    angle_tolerance_rad: float = 0.05
    """a joint within this of its aim counts as there, rad."""
    rest_speed_mps: float = 0.01
    """slower than this counts as at rest, m/s."""
    limits: CommandLimits = field(default_factory=CommandLimits)

    @property
    def clear_of_hopper_m(self) -> float:
        """Range from the loader's front to the hopper's centre at which the hopper may be spotted, m."""
        return self.hopper_half_length_m + self.hopper_wall_m + self.clearance_m


class CarryDumpScript:
    """The scripted carry, dump and return of one loading cycle; see the module docstring.

    Call :meth:`start` with the commanded targets the scoop left, then :meth:`act` once per control period
    until :attr:`done`.

    Args:
        params: poses, tolerances and limits.
    """

    def __init__(self, params: ScriptParams) -> None:
        self.params = params
        self.phase = "done"
        self.phase_time_s = 0.0
        self.timed_out: list[str] = []
        self.phase_times_s: dict[str, float] = {}
        self.targets = np.zeros(3)
        self._dump_held_s = 0.0

    @property
    def done(self) -> bool:
        """Whether the cycle's scripted part has ended."""
        return self.phase == "done"

    def start(self, targets: np.ndarray) -> None:
        """Begin a cycle's scripted part from the commanded targets (speed m/s, lift rad, tilt rad) the scoop left."""
        self.targets = np.array(targets, dtype=float)
        self.phase, self.phase_time_s, self._dump_held_s = PHASES[0], 0.0, 0.0
        self.timed_out, self.phase_times_s = [], {}

    def act(self, state: np.ndarray, ranges: Ranges) -> np.ndarray:
        """The action for this control period (3 numbers in [-1, 1], as a policy gives).

        Args:
            state: the 12-number state (:func:`autoscoop.core.state.build_state`).
            ranges: the tip's ranges to the hopper and the pile now.

        Returns:
            (3,) float32 action: drive, lift, tilt.
        """
        self._advance_phase(np.asarray(state, dtype=float), ranges)
        desired = self._desired(ranges)
        span = self.params.limits.high - self.params.limits.low
        action = np.clip((desired - self.targets) / span, -1.0, 1.0)
        self.targets = advance_targets(self.targets, action, self.params.limits)
        self.phase_time_s += self.params.control_period_s
        return action.astype(np.float32)

    def _advance_phase(self, state: np.ndarray, ranges: Ranges) -> None:
        """Move on to the next phase while the present one has ended (its aim reached or its time up)."""
        while not self.done:
            finished = self._finished(state, ranges)
            timed_out = self.phase_time_s >= self.params.phase_limit_s
            if not (finished or timed_out):
                return
            if timed_out and not finished:
                self.timed_out.append(self.phase)
            self.phase_times_s[self.phase] = self.phase_time_s
            self.phase = PHASES[PHASES.index(self.phase) + 1]
            self.phase_time_s, self._dump_held_s = 0.0, 0.0

    def _finished(self, state: np.ndarray, ranges: Ranges) -> bool:
        p = self.params
        speed, lift, tilt = state[STATE_SPEED], state[STATE_LIFT], state[STATE_TILT]
        if self.phase == "back_out":
            front_to_hopper = ranges.to_hopper_m + state[STATE_TIP_X] - LOADER_FRONT_M
            return front_to_hopper >= p.clear_of_hopper_m and abs(lift - p.carry_lift_rad) <= p.angle_tolerance_rad
        if self.phase == "to_hopper":
            return abs(ranges.to_hopper_m) <= p.position_tolerance_m and abs(speed) <= p.rest_speed_mps
        if self.phase == "dump":
            if abs(tilt - p.dump_tilt_rad) <= p.angle_tolerance_rad:
                self._dump_held_s += p.control_period_s
            return self._dump_held_s > p.dump_hold_s
        if self.phase == "back_off":
            return abs(tilt - p.carry_tilt_rad) <= p.angle_tolerance_rad
        if self.phase == "return":
            return (ranges.to_pile_m <= p.start_gap_m + p.position_tolerance_m and abs(speed) <= p.rest_speed_mps
                    and abs(lift - p.start_lift_rad) <= p.angle_tolerance_rad
                    and abs(tilt - p.start_tilt_rad) <= p.angle_tolerance_rad)
        return False

    def _desired(self, ranges: Ranges) -> np.ndarray:
        """Targets (speed m/s, lift rad, tilt rad) the present phase aims at."""
        p = self.params
        top = p.limits.max_speed_mps
        if self.phase == "back_out":
            return np.array([-top, p.carry_lift_rad, p.carry_tilt_rad])
        if self.phase == "to_hopper":
            return np.array([_approach_speed(ranges.to_hopper_m, top, p.control_period_s, backward=True),
                             p.carry_lift_rad, p.carry_tilt_rad])
        if self.phase == "back_off":
            return np.array([0.0, p.carry_lift_rad, p.carry_tilt_rad])
        if self.phase == "dump":
            return np.array([0.0, p.carry_lift_rad, p.dump_tilt_rad])
        if self.phase == "return":
            return np.array([_approach_speed(ranges.to_pile_m - p.start_gap_m, top, p.control_period_s),
                             p.start_lift_rad, p.start_tilt_rad])
        return np.array([0.0, self.targets[1], self.targets[2]])


def _approach_speed(remaining_m: float, top_speed_mps: float, period_s: float, backward: bool = False) -> float:
    """Speed that covers ``remaining_m`` (ahead positive) in one control period, at most ``top_speed_mps``; back
    only where ``backward``, m/s."""
    if not math.isfinite(remaining_m):
        return 0.0
    return float(np.clip(remaining_m / period_s, -top_speed_mps if backward else 0.0, top_speed_mps))
