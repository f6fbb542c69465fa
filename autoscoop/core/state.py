"""The paper's 12-number state and the action scaling: the one place the env, ROS node and exports use.

State, in this order (paper Sec. III-C; docs/definitions.md):

| index | name      | meaning                                               | unit | frame                   |
|-------|-----------|-------------------------------------------------------|------|-------------------------|
| 0     | w         | mass in the bucket / rated load                       | -    |                         |
| 1     | tip_x     | bucket cutting edge, forward                          | m    | chassis (x fwd from centre) |
| 2     | tip_z     | bucket cutting edge, up                               | m    | chassis (z up from ground)  |
| 3     | joint_x   | bucket (tilt) joint, forward                          | m    | chassis                 |
| 4     | joint_z   | bucket (tilt) joint, up                               | m    | chassis                 |
| 5     | d_pile    | distance from the tip to the pile's surface           | m    |                         |
| 6     | v         | forward drive speed (wheel odometry)                  | m/s  |                         |
| 7     | lift      | lift angle (positive lowers the arm)                  | rad  |                         |
| 8     | tilt      | tilt angle (positive tips the cutting edge down)      | rad  |                         |
| 9     | dv        | change of v since the previous step                   | m/s  |                         |
| 10    | dlift     | change of lift since the previous step                | rad  |                         |
| 11    | dtilt     | change of tilt since the previous step                | rad  |                         |

The tip and joint positions come from the arm's forward kinematics at the measured joint angles
(what the robot itself can compute), not from the simulator's ground truth. A policy trained with
``sensor.level_with_imu`` sees them in the *level* frame instead: the chassis frame turned by the
IMU's chassis pitch about the chassis centre, so that z is height above level ground even while the
loader rocks onto its front wheels (:func:`level_points`; ``STATE_FRAMES``).

Actions are 3 numbers in [-1, 1]: drive, lift, tilt. As in the paper's code, each one moves its
commanded target by ``action * (upper limit - lower limit)``, clipped to the limits.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from autoscoop.core import kinematics

if TYPE_CHECKING:
    from autoscoop.core.config import RobotConfig

STATE_NAMES = ("w", "tip_x", "tip_z", "joint_x", "joint_z", "d_pile", "v", "lift", "tilt", "dv", "dlift", "dtilt")
STATE_UNITS = ("-", "m", "m", "m", "m", "m", "m/s", "rad", "rad", "m/s", "rad", "rad")
STATE_SIZE = len(STATE_NAMES)
STATE_FRAMES = ("chassis", "level")
"""Frames of the state's tip and joint positions: ``chassis`` (the paper's; the arm's kinematics alone) or
``level`` (the same turned by the IMU's chassis pitch: gravity-level, x forward, z up)."""


def recorded_state_frame(metadata: dict, source: object) -> str:
    """The state frame a policy file's metadata records (``state_frame``; files from before it: ``chassis``).

    Raises:
        ValueError: naming ``source`` (the file), when the recorded frame is not one of :data:`STATE_FRAMES`.
    """
    frame = metadata.get("state_frame", "chassis")
    if frame not in STATE_FRAMES:
        raise ValueError(f"{source}: state_frame {frame!r} is not one of {STATE_FRAMES}")
    return frame


ACTION_NAMES = ("drive", "lift", "tilt")
ACTION_SIZE = len(ACTION_NAMES)


@dataclass(frozen=True)
class Measurements:
    """What the robot measures at one control step.

    Attributes:
        mass_kg: payload in the bucket (counted particles in simulation, torque estimate on the robot), kg.
        pile_distance_m: distance from the bucket tip to the pile, m (laser range on the robot).
        speed_mps: forward speed from wheel odometry, m/s.
        lift_rad: lift angle, rad (positive lowers the arm).
        tilt_rad: tilt angle, rad (positive tips the cutting edge down).
        chassis_pitch_rad: the IMU's chassis pitch, rad (positive nose down); 0 unless the state is
            wanted in the level frame, where the arm's points are turned by it (:func:`level_points`).
    """

    mass_kg: float
    pile_distance_m: float
    speed_mps: float
    lift_rad: float
    tilt_rad: float
    chassis_pitch_rad: float = 0.0


def level_points(points_xz: np.ndarray, chassis_pitch_rad: float | np.ndarray) -> np.ndarray:
    """Chassis-frame points (..., 2) in the level frame: turned by the chassis pitch about the chassis
    centre (:data:`autoscoop.core.kinematics.CHASSIS_CENTRE_HEIGHT_M` above the ground), so a point ahead
    of the centre drops as the nose pitches down. A pitch of exactly 0 returns the points unchanged."""
    pitch_rad = np.asarray(chassis_pitch_rad, dtype=float)
    if not np.any(pitch_rad):
        return points_xz
    centre = np.array([0.0, kinematics.CHASSIS_CENTRE_HEIGHT_M])
    return centre + kinematics.pitch(np.asarray(points_xz, dtype=float) - centre, pitch_rad)


def build_state(now: Measurements, previous: Measurements | None, rated_load_kg: float) -> np.ndarray:
    """The 12-number state (float32) from this step's and the previous step's measurements.

    Args:
        now: this step's measurements.
        previous: the previous step's, or ``None`` at the first step (changes are then zero).
        rated_load_kg: the bucket's rated load, for w = mass / rated load.

    Returns:
        (12,) float32 array in the order of :data:`STATE_NAMES`; (12, n) when the measurements are arrays of n.
    """
    before = now if previous is None else previous
    pose = kinematics.arm_pose(now.lift_rad, now.tilt_rad)
    tip = level_points(pose.tip, now.chassis_pitch_rad)
    joint = level_points(pose.bucket_joint, now.chassis_pitch_rad)
    return np.array([
        now.mass_kg / rated_load_kg,
        tip[..., 0], tip[..., 1],
        joint[..., 0], joint[..., 1],
        now.pile_distance_m,
        now.speed_mps, now.lift_rad, now.tilt_rad,
        now.speed_mps - before.speed_mps, now.lift_rad - before.lift_rad, now.tilt_rad - before.tilt_rad,
    ], dtype=np.float32)


@dataclass(frozen=True)
class CommandLimits:
    """Limits of the commanded targets.

    Attributes:
        max_speed_mps: drive speed limit, forward and back, m/s.
        lift_range_rad: (lower, upper) lift angle, rad.
        tilt_range_rad: (lower, upper) tilt angle, rad.
    """

    max_speed_mps: float = 0.1
    lift_range_rad: tuple[float, float] = kinematics.LIFT_RANGE_RAD
    tilt_range_rad: tuple[float, float] = kinematics.TILT_RANGE_RAD

    @classmethod
    def for_robot(cls, robot: RobotConfig) -> CommandLimits:
        """The limits of a configured robot: its drive speed limit, the arm's joint ranges."""
        return cls(max_speed_mps=robot.max_speed_mps)

    @property
    def low(self) -> np.ndarray:
        """Lower limits of (speed m/s, lift rad, tilt rad)."""
        return np.array([-self.max_speed_mps, self.lift_range_rad[0], self.tilt_range_rad[0]])

    @property
    def high(self) -> np.ndarray:
        """Upper limits of (speed m/s, lift rad, tilt rad)."""
        return np.array([self.max_speed_mps, self.lift_range_rad[1], self.tilt_range_rad[1]])


def validate_action(action: np.ndarray | list[float]) -> np.ndarray:
    """Check an action's shape and values; clip it to [-1, 1].

    Raises:
        ValueError: if the action does not hold 3 numbers or any is NaN or infinite (never clipped:
            a non-finite command means the controller is broken).
    """
    a = np.asarray(action, dtype=np.float64).reshape(-1)
    if a.shape != (ACTION_SIZE,):
        raise ValueError(f"action must hold {ACTION_SIZE} numbers {ACTION_NAMES}, got shape {np.shape(action)}")
    if not np.all(np.isfinite(a)):
        bad = [ACTION_NAMES[i] for i in np.flatnonzero(~np.isfinite(a))]
        raise ValueError(f"action has non-finite values in {bad}: {a.tolist()}; allowed range [-1, 1]")
    return np.clip(a, -1.0, 1.0)


def advance_targets(targets: np.ndarray, action: np.ndarray, limits: CommandLimits) -> np.ndarray:
    """Move the commanded targets (speed m/s, lift rad, tilt rad) by ``action * range``, clipped to the limits.

    Args:
        targets: (3,) current targets.
        action: (3,) action; validated and clipped to [-1, 1] here.
        limits: the targets' limits.

    Returns:
        (3,) new targets.
    """
    a = validate_action(action)
    low, high = limits.low, limits.high
    return np.clip(np.asarray(targets, dtype=np.float64) + a * (high - low), low, high)


def servo_rate(target: np.ndarray | float, setpoint: np.ndarray | float, period_s: float,
               max_speed: np.ndarray | float) -> np.ndarray:
    """How fast a linear actuator's setpoint moves toward its target: the whole way within one period,
    no faster than the actuator's speed (rad/s; arrays element-wise)."""
    speed = np.asarray(max_speed, dtype=float)
    return np.clip((np.asarray(target, dtype=float) - np.asarray(setpoint, dtype=float)) / period_s, -speed, speed)


STATE_CENTRE = np.array([0.5, 1.15, 0.15, 0.95, 0.2, 0.15, 0.0, 0.1, 0.2, 0.0, 0.0, 0.0], dtype=np.float32)
STATE_SCALE = np.array([0.5, 0.1, 0.15, 0.05, 0.1, 0.15, 0.1, 0.2, 0.7, 0.05, 0.1, 0.25], dtype=np.float32)
"""Fixed normalisation of the state for neural networks: (state - centre) / scale is about [-1, 1]
over the reachable states (w 0..1, the arm's workspace, speeds and joint ranges, one step's change)."""


FROUDE_EXPONENTS = np.array([0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.5, 0.0, 0.0, 0.0, -0.5, -0.5])
"""How each state number goes between two loaders alike under Froude scaling, lengths x S, with the same control
period: it is S ** exponent times the other's. w is a ratio (0); the tip, the joint and the pile distance are
lengths (1); the drive speed goes as sqrt(S) (0.5); the joint angles are the same (0); one period's change of
speed is an acceleration times the period, the same (0); one period's change of a joint angle is an angular speed
times the period, 1 / sqrt(S) (-0.5). The actions need no factor: each is a share of the machine's own range."""


def froude_input_factors(length_scale: float, history_steps: int) -> np.ndarray:
    """The factors (float64) by which the actor's input (:func:`actor_input_size` numbers) on a machine ``length_scale``
    times another's exceeds the input on that other in the same situation (:data:`FROUDE_EXPONENTS`; 1 for the
    commands of a history).

    Raises:
        ValueError: ``length_scale`` not a positive finite number.
    """
    if not (np.isfinite(length_scale) and length_scale > 0.0):
        raise ValueError(f"length scale {length_scale!r} must be a positive number")
    per_state = float(length_scale) ** FROUDE_EXPONENTS
    if history_steps == 1:
        return per_state
    return np.concatenate([np.tile(per_state, history_steps), np.ones(ACTION_SIZE * history_steps)])


ACTION_CENTRE = np.zeros(ACTION_SIZE, dtype=np.float32)
ACTION_SCALE = np.ones(ACTION_SIZE, dtype=np.float32)


MAX_HISTORY_STEPS = 8
"""the most states (and commands) an actor may read."""


def checked_history_steps(value: object, source: str) -> int:
    """``value`` as a ``history_steps`` (a whole number from 1 to :data:`MAX_HISTORY_STEPS`).

    Raises:
        ValueError: naming ``source`` (a file or a recipe) and the allowed range.
    """
    if not isinstance(value, int) or isinstance(value, bool) or not 1 <= value <= MAX_HISTORY_STEPS:
        shown = repr(value)[:200]
        raise ValueError(f"{source}: history_steps must be a whole number from 1 to {MAX_HISTORY_STEPS}, got {shown}")
    return value


def actor_input_size(history_steps: int) -> int:
    """How many numbers the actor reads: the 12-number state alone for ``history_steps`` 1 (the paper's),
    else that many states and as many earlier commands (:class:`ActorInputHistory`)."""
    if history_steps < 1:
        raise ValueError(f"history_steps must be >= 1, got {history_steps}")
    return STATE_SIZE if history_steps == 1 else history_steps * (STATE_SIZE + ACTION_SIZE)


def history_steps_for_input(size: int) -> int:
    """The ``history_steps`` whose actor input has ``size`` numbers (:func:`actor_input_size`).

    Raises:
        ValueError: when no history gives that size.
    """
    if size == STATE_SIZE:
        return 1
    steps, rest = divmod(size, STATE_SIZE + ACTION_SIZE)
    if rest or steps < 2:
        raise ValueError(f"an actor input of {size} numbers is neither the {STATE_SIZE}-number state nor a history "
                         f"of k >= 2 states and commands (k x {STATE_SIZE + ACTION_SIZE})")
    return steps


def actor_input_normalization(history_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """(centre, scale) of the actor's input for neural networks: the state's for each state of the history,
    none (0, 1) for the commands, which are already in [-1, 1]."""
    if history_steps == 1:
        return STATE_CENTRE, STATE_SCALE
    centre = np.concatenate([np.tile(STATE_CENTRE, history_steps), np.tile(ACTION_CENTRE, history_steps)])
    scale = np.concatenate([np.tile(STATE_SCALE, history_steps), np.tile(ACTION_SCALE, history_steps)])
    return centre.astype(np.float32), scale.astype(np.float32)


class ActorInputHistory:
    """The actor's input built from the states it has seen and the commands it gave: the one builder that
    training (an environment wrapper), evaluation, the ONNX runner and the ROS node share.

    With ``history_steps`` k >= 2 the input is, newest first,
    ``[s_t, s_t-1, ..., s_t-k+1, a_t-1, a_t-2, ..., a_t-k]`` (k states of :data:`STATE_NAMES`, then k
    actions of :data:`ACTION_NAMES`, each clipped to [-1, 1]): from how the arm, the wheels and the load
    answered its last commands, the controller can tell what it cannot measure (how heavy the earth is,
    how late its readings come). At an episode's start the first state stands for the states before it
    and the commands before it are 0 (the loader stands still). With k = 1 the input is the state alone.

    Args:
        history_steps: k, 1 or more.
    """

    def __init__(self, history_steps: int) -> None:
        self.history_steps = int(history_steps)
        self.size = actor_input_size(self.history_steps)
        self._states: list[np.ndarray] = []
        self._actions: list[np.ndarray] = []
        self.reset()

    def reset(self) -> None:
        """Forget the episode: the next state starts a new history."""
        self._states = []
        self._actions = [np.zeros(ACTION_SIZE, dtype=np.float32) for _ in range(self.history_steps)]

    def observe(self, state: np.ndarray) -> np.ndarray:
        """The actor's input (float32, :attr:`size` numbers) with ``state`` as the newest state."""
        state = np.asarray(state, dtype=np.float32).reshape(STATE_SIZE)
        if self.history_steps == 1:
            return state.copy()
        if not self._states:
            self._states = [state] * self.history_steps
        else:
            self._states = [state, *self._states[:-1]]
        return np.concatenate([*self._states, *self._actions]).astype(np.float32)

    def acted(self, action: np.ndarray) -> None:
        """Record the command given for the last observed state (clipped to [-1, 1], as the robot applies it)."""
        if self.history_steps == 1:
            return
        clipped = np.clip(np.asarray(action, dtype=np.float32).reshape(ACTION_SIZE), -1.0, 1.0)
        self._actions = [clipped, *self._actions[:-1]]
