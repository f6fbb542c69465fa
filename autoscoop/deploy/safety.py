"""The node's safety layer, free of ROS: an input watchdog and a command limiter.

Both are plain classes with no clock of their own: every call takes ``now`` (seconds on a monotonic
clock), so tests drive them with made-up times. Neither is a substitute for the robot's hardware
emergency stop: they only decide what the node publishes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from autoscoop.deploy.robot_config import LimitsSection


@dataclass(frozen=True)
class Stamp:
    """When a stamped message's reading was taken, as the message and the node's clock tell it.

    Attributes:
        header_s: the message's ``header.stamp``, s on the sender's ROS clock (0: not stamped).
        clock_s: the node's ROS clock (``rospy.get_time()``) when the message arrived, s.
    """

    header_s: float
    clock_s: float

    @property
    def age_s(self) -> float:
        """How old the reading was when it arrived, s (negative: stamped ahead of the node's clock)."""
        return self.clock_s - self.header_s


class InputWatchdog:
    """Tracks when each input's latest valid reading was taken, and which inputs are bad.

    An input is *healthy* when its latest message was valid and its reading was taken at most
    ``timeout_s`` ago. A reading is taken when its message arrives, or, for a message with a header
    (a :class:`Stamp`), at its stamp: a driver that re-publishes an old reading, or stamps it late,
    cannot keep an input fresh. A message that fails the checks makes its input bad at once, until a
    valid one arrives; for a stamped message the checks are, besides its values (the caller's):

    - stamped (``header.stamp`` not 0);
    - at most ``max_future_s`` ahead of the node's clock (clock skew); up to that, it counts as taken
      on arrival;
    - at most ``timeout_s`` old on arrival;
    - not older than the input's last accepted stamp, while that one is fresh (out of order: two
      publishers, or a clock stepped back). Once the input has gone stale, its order starts afresh.

    A message that repeats the last accepted stamp (a frozen driver) is ignored: it neither refreshes
    the input nor makes it bad, so the input goes stale ``timeout_s`` after that stamp.

    Args:
        names: the inputs watched, e.g. ``("joint_states", "odom", ...)``.
        timeout_s: largest allowed age of an input, s.
        max_future_s: how far ahead of the node's clock a stamp may be, s.
    """

    def __init__(self, names: tuple[str, ...] | list[str], timeout_s: float, max_future_s: float = 0.1) -> None:
        if not (timeout_s > 0 and math.isfinite(timeout_s)):
            raise ValueError(f"watchdog timeout must be a positive number of seconds, got {timeout_s}")
        if not (max_future_s >= 0 and math.isfinite(max_future_s)):
            raise ValueError(f"watchdog future-stamp bound must be a finite number of seconds >= 0, got {max_future_s}")
        self.names = tuple(names)
        self.timeout_s = float(timeout_s)
        self.max_future_s = float(max_future_s)
        self._last_valid: dict[str, float | None] = {name: None for name in self.names}
        self._last_stamp: dict[str, float] = {}
        self._bad: dict[str, str] = {}

    def valid(self, name: str, now: float, stamp: Stamp | None = None) -> bool:
        """A reading of ``name`` that passed its value checks arrived at ``now``; whether it is taken.

        Without ``stamp`` it is taken as read at ``now``. With one, it may be refused (the input is
        then bad, and ``False`` returned) or ignored as a repeat (``False``, the input unchanged); see
        the class docstring. An input not watched is ignored (``True``).
        """
        if name not in self._last_valid:
            return True
        taken = now if stamp is None else self._taken(name, now, stamp)
        if taken is None:
            return False
        last = self._last_valid[name]
        self._last_valid[name] = taken if last is None else max(last, taken)
        self._bad.pop(name, None)
        return True

    def _taken(self, name: str, now: float, stamp: Stamp) -> float | None:
        """When a stamped reading was taken on the ``now`` clock; ``None`` when refused (marked bad) or a repeat.

        The reasons hold no per-message numbers, so that a run of refused messages is one fault (one
        log line, one status), not one per message."""
        header, age = stamp.header_s, stamp.age_s
        previous = self._last_stamp.get(name)
        if header == previous:  # a repeat: the input ages from its stamp (one "stale" fault, not one per message)
            return None
        last = self._last_valid[name]
        in_order = previous is None or header > previous or (last is not None and now - last > self.timeout_s)
        why = ""
        if not (math.isfinite(header) and header > 0 and math.isfinite(age)):
            why = "message not stamped (header.stamp 0): its age cannot be judged"
        elif age < -self.max_future_s:
            why = f"stamped over {self.max_future_s:g} s ahead of the node's clock"
        elif age > self.timeout_s:
            why = f"stamped over {self.timeout_s:g} s ago"
        elif not in_order:
            why = "stamped before the last accepted message (out of order)"
        if why:
            self.invalid(name, why)
            return None
        self._last_stamp[name] = header
        return now - max(age, 0.0)

    def invalid(self, name: str, why: str) -> None:
        """A reading of ``name`` failed its checks (``why`` says how); the input is bad until the next valid one."""
        if name in self._last_valid:
            self._bad[name] = why

    def problems(self, now: float) -> list[str]:
        """Why the inputs are not all healthy at ``now``; empty when they are."""
        out = []
        for name in self.names:
            last = self._last_valid[name]
            if name in self._bad:
                out.append(f"{name}: {self._bad[name]}")
            elif last is None:
                out.append(f"{name}: no message yet")
            elif now - last > self.timeout_s:
                out.append(f"{name}: stale (no valid message for over {self.timeout_s:g} s)")
        return out

    def next_expiry(self, now: float) -> float:
        """The earliest time after ``now`` that a healthy input goes stale (``inf`` when none can)."""
        times = [last + self.timeout_s for name, last in self._last_valid.items()
                 if last is not None and name not in self._bad and last + self.timeout_s >= now]
        return min(times, default=math.inf)


@dataclass(frozen=True)
class Command:
    """What the node publishes at one instant.

    Attributes:
        speed_mps: forward speed for ``cmd_vel``, m/s.
        lift_rad: lift position command, rad; ``None`` publishes no arm command (the joint
            controllers keep their last setpoint).
        tilt_rad: tilt position command, rad; ``None`` as for lift.
        mode: ``idle`` (no scoop running), ``running``, ``fault`` (watchdog) or ``estop``.
        reason: why the robot is stopped, or ``""``.
    """

    speed_mps: float
    lift_rad: float | None
    tilt_rad: float | None
    mode: str
    reason: str = ""

    def as_array(self) -> np.ndarray:
        """(speed, lift, tilt), NaN where no arm command is published."""
        return np.array([self.speed_mps, np.nan if self.lift_rad is None else self.lift_rad,
                         np.nan if self.tilt_rad is None else self.tilt_rad])


class CommandLimiter:
    """Clamps commands to the robot's limits: speed, joint ranges and rate of change.

    Args:
        limits: the robot's ``limits`` section.
        period_s: time between two commands of the control loop, s (the rate limits' step).
    """

    def __init__(self, limits: LimitsSection, period_s: float) -> None:
        self.limits = limits
        self.low = np.array([-limits.max_speed_mps, limits.lift_min_rad, limits.tilt_min_rad])
        self.high = np.array([limits.max_speed_mps, limits.lift_max_rad, limits.tilt_max_rad])
        self.step = np.array([limits.max_accel_mps2, limits.lift_rate_radps, limits.tilt_rate_radps]) * period_s

    def clamp(self, desired: np.ndarray, last: np.ndarray | None) -> np.ndarray:
        """(speed, lift, tilt) within the limits and at most one step from ``last``.

        Args:
            desired: (3,) wished-for (speed m/s, lift rad, tilt rad); non-finite entries keep ``last``
                (or the nearest limit to zero when there is no ``last``).
            last: (3,) the previous published command, or ``None``.

        Returns:
            (3,) finite command within the limits.
        """
        wish = np.asarray(desired, dtype=float).copy()
        before = None if last is None else np.asarray(last, dtype=float)
        fallback = np.clip(np.zeros(3), self.low, self.high) if before is None else before
        bad = ~np.isfinite(wish)
        wish[bad] = fallback[bad]
        out = np.clip(wish, self.low, self.high)
        if before is not None and np.all(np.isfinite(before)):
            out = np.clip(out, before - self.step, before + self.step)
            out = np.clip(out, self.low, self.high)
        return out

    def hold(self, arm: np.ndarray | None) -> np.ndarray | None:
        """The arm command (lift, tilt) that holds the arm where it was last commanded, inside the limits."""
        if arm is None or not np.all(np.isfinite(arm)):
            return None
        return np.clip(np.asarray(arm, dtype=float), self.low[1:], self.high[1:])

    def contains(self, command: Command) -> bool:
        """Whether a command is finite and inside the limits (a check for tests and the node's last guard)."""
        values = command.as_array()
        finite = np.isfinite(values)
        if not finite[0] or (command.lift_rad is None) != (command.tilt_rad is None):
            return False
        return bool(np.all(values[finite] >= self.low[finite] - 1e-12) and
                    np.all(values[finite] <= self.high[finite] + 1e-12))
