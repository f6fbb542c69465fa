"""Payload mass from the arm's joint torques (paper eq. 4 and eq. 8), numpy only.

The real robot cannot count particles: it measures the torques that hold the arm and the bucket and
turns them into the mass in the bucket. This module holds the arm's planar statics for that: the
Jacobian of a point of the bucket, the gravity torques ``G`` of the known links, two estimators and
their calibration. It never imports the simulator; :mod:`autoscoop.sim.load_cell` feeds it the
simulator's readings and the ROS node feeds it the robot's, both as :class:`PayloadReading` s averaged
over the control period by :class:`ReadingAverage`.

Frames and signs (the same as :mod:`autoscoop.core.kinematics`, which holds every dimension):

* chassis frame: x forward from the chassis centre, z up from the ground, metres; the arm moves in
  this x-z plane. Gravity is taken along -z of this frame unless the chassis pitch is given
  (``chassis_pitch_rad``, from the IMU; positive = nose down, about +y like the joints).
* bucket frame: origin at the tilt joint, x toward the cutting edge, z toward the bucket's mouth.
* joint angles ``q = (lift, tilt)``, rad; both turn about +y, so a positive angle pitches forward-down.
* torques ``tau = (lift, tilt)``, N*m: what the actuators apply to the joints about +y (MuJoCo's
  ``jointactuatorfrc``). Holding a load forward of a joint takes a *negative* torque.

Static equilibrium of the arm (paper eq. 8)::

    tau = G(q) + J(q)^T f + offset

``G = sum_i J_i^T (m_i g up)`` is the torque that holds up the arm and the empty bucket, ``J`` is the
2x2 Jacobian d(point)/dq of the point where the payload acts, and ``f`` is the force the bucket
exerts on the payload to hold it: at rest ``f = m g up``. With ``f`` along ``up`` only the payload's
line of action matters, and the two joint torques give both unknowns, the mass and that line, so
eq. 8 needs no lever arm::

    m g = ((tau_T - G_T) - (tau_L - G_L)) / (h(p_T) - h(p_L))

where ``h`` is the horizontal coordinate (perpendicular to ``up``) and ``p_L``, ``p_T`` are the lift
and tilt joints. The paper's eq. 4 uses the bucket joint alone, ``tau = V gamma g r_cm``: it needs the
payload's lever arm ``r_cm`` (the horizontal distance from the tilt joint to the payload's centre of
mass), which comes from a calibrated point in the bucket frame, and it is some ten times more
sensitive to torque noise, because that lever arm is short.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from autoscoop.core import kinematics
from autoscoop.core.safe_files import quote, read_yaml, write_text_atomically

GRAVITY_MPS2 = 9.81
"""Standard gravity (MuJoCo's default), m/s^2."""
ARM_COM_IN_ARM_M = (np.asarray(kinematics.TILT_JOINT_FROM_LIFT_JOINT_M)
                    * kinematics.ARM_COM_ALONG_M / np.hypot(*kinematics.TILT_JOINT_FROM_LIFT_JOINT_M))
"""Arm link's centre of mass in the arm frame (lift joint origin, arm at zero), (x, z) m: on the
line from the lift joint to the tilt joint."""
BUCKET_COM_IN_BUCKET_M = np.array([kinematics.BUCKET_COM_FROM_TILT_JOINT_M, 0.0])
"""Empty bucket's centre of mass in the bucket frame, (x, z) m."""
DEFAULT_PAYLOAD_COM_IN_BUCKET_M = (0.099, 0.008)
"""Centroid of the in-bucket quadrilateral (bucket frame, m): the payload's lever-arm point before calibration."""
CALIBRATION_FORMAT = "autoscoop-payload-calibration/1"
FIT_RCOND = 1e-2
"""Directions of the (column-scaled) calibration fit weaker than this fraction of the strongest are
left at the prior: holds at a single bucket angle (which differ only by the arm's sag under load)
do not tell the lever arm's two components apart, and fitting them would fit noise."""


# ------------------------------------------------------------------------- readings
@dataclass(frozen=True)
class PayloadReading:
    """One set of the robot's readings for the payload estimate (simulated or real; frames as the module's).

    Attributes:
        lift_rad: lift joint angle, rad, about +y (positive pitches the arm forward-down).
        tilt_rad: tilt (bucket) joint angle, rad, about +y, relative to the arm.
        lift_torque_nm: actuator torque at the lift joint about +y, N*m (negative holds a load forward).
        tilt_torque_nm: actuator torque at the tilt (bucket) joint about +y, N*m; the ROS topic
            ``bucket_torque`` carries it.
        chassis_pitch_rad: chassis pitch from the IMU, rad, positive nose down (about +y); 0 takes
            gravity along the chassis' -z.
    """

    lift_rad: float
    tilt_rad: float
    lift_torque_nm: float
    tilt_torque_nm: float
    chassis_pitch_rad: float = 0.0

    def as_array(self) -> np.ndarray:
        """(5,) array in the field order (:data:`READING_FIELDS`)."""
        return np.array([self.lift_rad, self.tilt_rad, self.lift_torque_nm, self.tilt_torque_nm,
                         self.chassis_pitch_rad])


READING_FIELDS = ("lift_rad", "tilt_rad", "lift_torque_nm", "tilt_torque_nm", "chassis_pitch_rad")
"""The fields of :class:`PayloadReading`, in order."""
_FIELD_INDEX = {name: i for i, name in enumerate(READING_FIELDS)}


class ReadingAverage:
    """The mean of the :class:`PayloadReading` s added since it was last taken: the load cell's averaging.

    A controller sees the payload's readings averaged over its control period, because particles
    rattling in the servo-held bucket swing a single reading by a kilogram or more. The simulator's
    load cell adds one full reading per physics step; the ROS controller adds each message's fields
    as they arrive (``fields``), so each field is averaged over the readings of that field. Each mean
    is the sum of the readings divided by their count.
    """

    def __init__(self) -> None:
        self._sum = np.zeros(len(READING_FIELDS))
        self._count = np.zeros(len(READING_FIELDS), dtype=np.int64)
        self._last = np.full(len(READING_FIELDS), math.nan)

    def add(self, reading: PayloadReading, fields: tuple[str, ...] = READING_FIELDS) -> None:
        """Add ``reading``'s ``fields`` (default: all of them); its other fields are ignored."""
        values = reading.as_array()
        if fields is READING_FIELDS or fields == READING_FIELDS:
            self._sum += values
            self._count += 1
            self._last[:] = values
            return
        index = [_FIELD_INDEX[name] for name in fields]
        self._sum[index] += values[index]
        self._count[index] += 1
        self._last[index] = values[index]

    def take(self) -> PayloadReading | None:
        """The mean reading since the last take, then start over; ``None`` when nothing was added since.

        A field with no reading since the last take keeps its last value (NaN if it never had one)."""
        counted = self._count > 0
        if not counted.any():
            return None
        mean = self._last.copy()
        mean[counted] = self._sum[counted] / self._count[counted]
        self.restart()
        return PayloadReading(*(float(v) for v in mean))

    @property
    def latest(self) -> PayloadReading:
        """The last value of each field (NaN where none was ever added)."""
        return PayloadReading(*(float(v) for v in self._last))

    def restart(self) -> None:
        """Start the means over (a scoop starts); the last values stay."""
        self._sum[:] = 0.0
        self._count[:] = 0


# ------------------------------------------------------------------------- kinematics and Jacobians
def up_in_chassis(chassis_pitch_rad: float | np.ndarray = 0.0) -> np.ndarray:
    """Unit vector opposite to gravity in the chassis frame, (..., 2) (x, z).

    Args:
        chassis_pitch_rad: chassis pitch, rad; positive = nose down (about +y).
    """
    phi = np.asarray(chassis_pitch_rad, dtype=float)
    return np.stack([-np.sin(phi), np.cos(phi)], axis=-1)


def pitch_from_quaternion(w: float, x: float, y: float, z: float) -> float:
    """Chassis pitch (rad, positive nose down, about +y) from an orientation quaternion; 0 if it is not a rotation.

    Wheel odometry often leaves the orientation at zero (not a rotation) or at a pure yaw: both give 0.
    """
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if not math.isfinite(norm) or norm < 0.5:
        return 0.0
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    # world up in the chassis frame is the rotation matrix's last row: (2(xz - wy), 2(yz + wx), 1 - 2(x^2 + y^2))
    return math.atan2(-2.0 * (x * z - w * y), 1.0 - 2.0 * (x * x + y * y))


def horizontal(point_xz: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Coordinate of chassis-frame points along the horizontal (perpendicular to ``up``, forward), (...,) m."""
    p, u = np.asarray(point_xz, dtype=float), np.asarray(up, dtype=float)
    return p[..., 0] * u[..., 1] - p[..., 1] * u[..., 0]


def _perp(r: np.ndarray) -> np.ndarray:
    """d/dq of a lever vector ``r`` turning with a joint about +y: (r_z, -r_x)."""
    return np.stack([r[..., 1], -r[..., 0]], axis=-1)


def arm_com(lift_rad: float | np.ndarray) -> np.ndarray:
    """Arm link's centre of mass in the chassis frame, (..., 2) m."""
    return kinematics.LIFT_JOINT_M + kinematics.pitch(ARM_COM_IN_ARM_M, np.asarray(lift_rad, dtype=float))


def bucket_com(lift_rad: float | np.ndarray, tilt_rad: float | np.ndarray) -> np.ndarray:
    """Empty bucket's centre of mass in the chassis frame, (..., 2) m."""
    return kinematics.bucket_point(lift_rad, tilt_rad, BUCKET_COM_IN_BUCKET_M)


def bucket_point_jacobian(lift_rad: float | np.ndarray, tilt_rad: float | np.ndarray,
                          point_in_bucket_m: np.ndarray) -> np.ndarray:
    """Jacobian of a point fixed in the bucket, in the chassis frame.

    Args:
        lift_rad: lift angle(s), rad.
        tilt_rad: tilt angle(s), rad.
        point_in_bucket_m: (2,) the point (x, z) in the bucket frame, m.

    Returns:
        (..., 2, 2) array ``J[..., i, j] = d p_i / d q_j`` with ``p = (x, z)`` and ``q = (lift, tilt)``.
    """
    p = kinematics.bucket_point(lift_rad, tilt_rad, point_in_bucket_m)
    joint = kinematics.bucket_joint_position(lift_rad)
    return np.stack([_perp(p - kinematics.LIFT_JOINT_M), _perp(p - joint)], axis=-1)


def arm_point_jacobian(lift_rad: float | np.ndarray, point_in_arm_m: np.ndarray) -> np.ndarray:
    """Jacobian of a point fixed in the arm link (arm frame at the lift joint), (..., 2, 2); tilt column zero."""
    lift = np.asarray(lift_rad, dtype=float)
    r = kinematics.pitch(np.asarray(point_in_arm_m, dtype=float), lift)
    return np.stack([_perp(r), np.zeros_like(r)], axis=-1)


def gravity_torques(lift_rad: float | np.ndarray, tilt_rad: float | np.ndarray,
                    chassis_pitch_rad: float | np.ndarray = 0.0, gravity_mps2: float = GRAVITY_MPS2) -> np.ndarray:
    """``G``: the actuator torques that hold the arm and the empty bucket still (paper eq. 8).

    ``G = sum_i J_i^T (m_i g up)`` over the arm link and the bucket, at their centres of mass.

    Args:
        lift_rad: measured lift angle(s), rad.
        tilt_rad: measured tilt angle(s), rad.
        chassis_pitch_rad: chassis pitch, rad (positive nose down); 0 takes gravity along -z.
        gravity_mps2: gravitational acceleration, m/s^2.

    Returns:
        (..., 2) torques (lift, tilt), N*m, sign as the actuators' (negative holds a load forward).
    """
    up = up_in_chassis(chassis_pitch_rad)
    j_arm = arm_point_jacobian(lift_rad, ARM_COM_IN_ARM_M)
    j_bucket = bucket_point_jacobian(lift_rad, tilt_rad, BUCKET_COM_IN_BUCKET_M)
    weight_arm = kinematics.ARM_MASS_KG * gravity_mps2 * up
    weight_bucket = kinematics.BUCKET_MASS_KG * gravity_mps2 * up
    return (np.einsum("...ij,...i->...j", j_arm, weight_arm)
            + np.einsum("...ij,...i->...j", j_bucket, weight_bucket))


def payload_force(lift_rad: float, tilt_rad: float, torques_nm: np.ndarray, point_in_bucket_m: np.ndarray,
                  chassis_pitch_rad: float = 0.0, gravity_mps2: float = GRAVITY_MPS2) -> np.ndarray:
    """Solve eq. 8 for the force ``f`` the bucket exerts at a known point: ``J^T f = tau - G``.

    Useful where the load is not a resting weight (a push from the pile); for a resting payload,
    :func:`mass_eq8` needs no point.

    Args:
        lift_rad: lift angle, rad.
        tilt_rad: tilt angle, rad.
        torques_nm: (2,) measured (lift, tilt) torques, offsets already removed, N*m.
        point_in_bucket_m: (2,) where the force acts, bucket frame, m.
        chassis_pitch_rad: chassis pitch, rad.
        gravity_mps2: m/s^2.

    Returns:
        (2,) force (x, z) in the chassis frame, N.
    """
    residual = np.asarray(torques_nm, dtype=float) - gravity_torques(lift_rad, tilt_rad, chassis_pitch_rad,
                                                                       gravity_mps2)
    return np.linalg.solve(bucket_point_jacobian(lift_rad, tilt_rad, point_in_bucket_m).T, residual)


# ------------------------------------------------------------------------- calibration and estimators
MAX_CALIBRATION_BYTES = 64 << 10
"""cap of a calibration file, bytes (one is about 1 KB)."""


@dataclass(frozen=True)
class PayloadCalibration:
    """What the torque estimators need beyond the link masses; written by ``autoscoop payload calibrate``.

    Attributes:
        lift_offset_nm: lift torque reading with nothing to hold beyond ``G`` (sensor zero), N*m.
        tilt_offset_nm: tilt torque reading with nothing to hold beyond ``G``, N*m.
        payload_com_in_bucket_m: the payload's centre of mass in the bucket frame, (x, z) m: eq. 4's lever arm.
        gravity_mps2: gravitational acceleration, m/s^2.
        fit: how it was fitted (records, samples, residuals); informational.
    """

    lift_offset_nm: float = 0.0
    tilt_offset_nm: float = 0.0
    payload_com_in_bucket_m: tuple[float, float] = DEFAULT_PAYLOAD_COM_IN_BUCKET_M
    gravity_mps2: float = GRAVITY_MPS2
    fit: dict[str, Any] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        com = tuple(float(v) for v in self.payload_com_in_bucket_m)
        if len(com) != 2 or not all(np.isfinite(com)):
            raise ValueError(f"payload_com_in_bucket_m must be two finite numbers (x, z) in m, got {com}")
        if not 0.01 <= com[0] <= kinematics.TIP_FROM_TILT_JOINT_M:
            raise ValueError(f"payload_com_in_bucket_m x = {com[0]:.4f} m is outside the bucket; allowed "
                             f"[0.01, {kinematics.TIP_FROM_TILT_JOINT_M}] m")
        object.__setattr__(self, "payload_com_in_bucket_m", com)
        for name in ("lift_offset_nm", "tilt_offset_nm", "gravity_mps2"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite, got {getattr(self, name)}")
        if not 1.0 <= self.gravity_mps2 <= 30.0:
            raise ValueError(f"gravity_mps2 = {self.gravity_mps2} is out of range; allowed [1, 30] m/s^2")

    @property
    def offsets_nm(self) -> np.ndarray:
        """(lift, tilt) torque offsets, N*m."""
        return np.array([self.lift_offset_nm, self.tilt_offset_nm])

    def save(self, path: str | Path) -> Path:
        """Write the calibration as a small YAML file."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        data = {"format": CALIBRATION_FORMAT, **asdict(self)}
        data["payload_com_in_bucket_m"] = [float(v) for v in self.payload_com_in_bucket_m]
        header = ("# autoscoop payload calibration: torque offsets (N*m) and the payload's centre of mass in the\n"
                  "# bucket frame (x to the cutting edge, z to the mouth; m). See autoscoop/core/payload.py.\n")
        write_text_atomically(path, header + yaml.safe_dump(data, sort_keys=False))
        return path

    @classmethod
    def load(cls, path: str | Path) -> PayloadCalibration:
        """Read a calibration written by :meth:`save` (within bounds: :func:`autoscoop.core.safe_files.read_yaml`).

        Raises:
            ValueError: the file is missing, too large, not YAML, not a calibration, or holds an unknown key or a
                value out of range (the message names the file).
        """
        data = read_yaml(path, "calibration", limit=MAX_CALIBRATION_BYTES) or {}
        if not isinstance(data, dict) or data.pop("format", None) != CALIBRATION_FORMAT:
            raise ValueError(f"{path}: not an autoscoop payload calibration (expected format: {CALIBRATION_FORMAT})")
        known = {"lift_offset_nm", "tilt_offset_nm", "payload_com_in_bucket_m", "gravity_mps2", "fit"}
        unknown = set(data) - known
        if unknown:
            raise ValueError(f"{path}: unknown calibration key(s) {sorted(unknown)}; known: {sorted(known)}")
        try:
            if "payload_com_in_bucket_m" in data:
                data["payload_com_in_bucket_m"] = tuple(data["payload_com_in_bucket_m"])
            return cls(**data)
        except (TypeError, ValueError) as error:
            raise ValueError(f"calibration {path}: {quote(str(error), 300)}") from None


def _payload_torques(lift_rad, tilt_rad, lift_torque_nm, tilt_torque_nm, calibration, chassis_pitch_rad):
    """Measured torques less ``G`` and the offsets: what the payload alone takes, (..., 2) N*m."""
    g = gravity_torques(lift_rad, tilt_rad, chassis_pitch_rad, calibration.gravity_mps2)
    measured = np.stack(np.broadcast_arrays(np.asarray(lift_torque_nm, dtype=float),
                                            np.asarray(tilt_torque_nm, dtype=float)), axis=-1)
    return measured - g - calibration.offsets_nm


def mass_eq8(lift_rad: float | np.ndarray, tilt_rad: float | np.ndarray, lift_torque_nm: float | np.ndarray,
             tilt_torque_nm: float | np.ndarray, calibration: PayloadCalibration | None = None,
             chassis_pitch_rad: float | np.ndarray = 0.0) -> np.ndarray:
    """Payload mass from both joint torques (static equilibrium of the arm, paper eq. 8), kg.

    Solves ``tau - G - offset = J^T f`` with ``f = m g up`` acting on an unknown line of action (see
    the module docstring): no lever arm is needed. Not clipped: noise gives small negative masses.

    Args:
        lift_rad: measured lift angle(s), rad.
        tilt_rad: measured tilt angle(s), rad.
        lift_torque_nm: measured lift actuator torque(s), N*m.
        tilt_torque_nm: measured tilt actuator torque(s), N*m.
        calibration: torque offsets and gravity; defaults to :class:`PayloadCalibration` ().
        chassis_pitch_rad: chassis pitch from the IMU, rad (positive nose down).

    Returns:
        Mass(es), kg.
    """
    calibration = calibration or PayloadCalibration()
    tau = _payload_torques(lift_rad, tilt_rad, lift_torque_nm, tilt_torque_nm, calibration, chassis_pitch_rad)
    up = up_in_chassis(chassis_pitch_rad)
    span = horizontal(kinematics.bucket_joint_position(lift_rad), up) - horizontal(kinematics.LIFT_JOINT_M, up)
    return (tau[..., 1] - tau[..., 0]) / (calibration.gravity_mps2 * span)


def payload_line_of_action(lift_rad: float | np.ndarray, tilt_rad: float | np.ndarray,
                           lift_torque_nm: float | np.ndarray, tilt_torque_nm: float | np.ndarray,
                           calibration: PayloadCalibration | None = None,
                           chassis_pitch_rad: float | np.ndarray = 0.0) -> np.ndarray:
    """Eq. 8's second unknown: horizontal distance from the tilt joint to the payload's centre of mass, m.

    Ill-defined (division by the mass) when the bucket is nearly empty.
    """
    calibration = calibration or PayloadCalibration()
    tau = _payload_torques(lift_rad, tilt_rad, lift_torque_nm, tilt_torque_nm, calibration, chassis_pitch_rad)
    weight = calibration.gravity_mps2 * mass_eq8(lift_rad, tilt_rad, lift_torque_nm, tilt_torque_nm, calibration,
                                                 chassis_pitch_rad)
    return -tau[..., 1] / weight


def payload_lever_arm(lift_rad: float | np.ndarray, tilt_rad: float | np.ndarray,
                      calibration: PayloadCalibration | None = None,
                      chassis_pitch_rad: float | np.ndarray = 0.0) -> np.ndarray:
    """Eq. 4's ``r_cm``: horizontal distance from the tilt joint to the calibrated payload centre of mass, m."""
    calibration = calibration or PayloadCalibration()
    offset = kinematics.pitch(np.asarray(calibration.payload_com_in_bucket_m),
                              kinematics.bucket_angle(lift_rad, tilt_rad))
    return horizontal(offset, up_in_chassis(chassis_pitch_rad))


def mass_eq4(lift_rad: float | np.ndarray, tilt_rad: float | np.ndarray, tilt_torque_nm: float | np.ndarray,
             calibration: PayloadCalibration | None = None,
             chassis_pitch_rad: float | np.ndarray = 0.0) -> np.ndarray:
    """Payload mass from the bucket joint's torque alone (paper eq. 4, ``tau = V gamma g r_cm``), kg.

    ``r_cm`` is :func:`payload_lever_arm`, from the calibrated payload centre of mass; where the real
    payload's centre lies elsewhere (a heaped or a half-empty bucket), the estimate is off in proportion.

    Args:
        lift_rad: measured lift angle(s), rad.
        tilt_rad: measured tilt angle(s), rad.
        tilt_torque_nm: measured tilt actuator torque(s), N*m.
        calibration: offsets, payload centre of mass, gravity.
        chassis_pitch_rad: chassis pitch from the IMU, rad.

    Returns:
        Mass(es), kg; NaN where the lever arm vanishes (payload centre above the joint).
    """
    calibration = calibration or PayloadCalibration()
    tau = _payload_torques(lift_rad, tilt_rad, 0.0, tilt_torque_nm, calibration, chassis_pitch_rad)
    lever = payload_lever_arm(lift_rad, tilt_rad, calibration, chassis_pitch_rad)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.abs(lever) > 1e-3, -tau[..., 1] / (calibration.gravity_mps2 * lever), np.nan)


ESTIMATORS = ("eq8", "eq4")


@dataclass(frozen=True)
class PayloadEstimator:
    """A calibrated torque-to-mass estimator, as the environment's load cell and the ROS node use it.

    Args:
        calibration: offsets and payload centre of mass.
        method: ``eq8`` (both joints, default) or ``eq4`` (bucket joint only).
    """

    calibration: PayloadCalibration = field(default_factory=PayloadCalibration)
    method: str = "eq8"

    def __post_init__(self) -> None:
        if self.method not in ESTIMATORS:
            raise ValueError(f"payload estimator method {self.method!r} is not allowed; choose one of {list(ESTIMATORS)}")

    @classmethod
    def from_yaml(cls, path: str | Path, method: str = "eq8") -> PayloadEstimator:
        """The estimator with a calibration file written by ``autoscoop payload calibrate``."""
        return cls(PayloadCalibration.load(path), method)

    def mass_kg(self, reading: PayloadReading) -> float:
        """Payload mass from one set of readings, kg; not clipped (eq. 4 ignores the lift torque)."""
        r = reading
        if self.method == "eq4":
            return float(mass_eq4(r.lift_rad, r.tilt_rad, r.tilt_torque_nm, self.calibration, r.chassis_pitch_rad))
        return float(mass_eq8(r.lift_rad, r.tilt_rad, r.lift_torque_nm, r.tilt_torque_nm, self.calibration,
                              r.chassis_pitch_rad))


def reported_mass_kg(estimate_kg: float, previous_kg: float, empty_below_kg: float = 0.0) -> float:
    """What the load cell reports from one raw estimate, kg: the one rule the environment and the ROS node share.

    Args:
        estimate_kg: the estimator's mass (eq. 8 or eq. 4), not clipped; NaN or infinite where the
            estimate is undefined (eq. 4 with the payload's centre right above the tilt joint).
        previous_kg: the previous report, kept when the estimate is undefined.
        empty_below_kg: estimates below this read 0 (noise on an empty bucket; a particle count never
            goes below zero). ``-inf`` reports negative estimates as they are.
    """
    if not math.isfinite(estimate_kg):
        return previous_kg
    return estimate_kg if estimate_kg >= empty_below_kg else 0.0


# ------------------------------------------------------------------------- fitting
def fit_calibration(lift_rad: np.ndarray, tilt_rad: np.ndarray, lift_torque_nm: np.ndarray,
                    tilt_torque_nm: np.ndarray, mass_kg: np.ndarray, chassis_pitch_rad: np.ndarray | float = 0.0,
                    prior: PayloadCalibration | None = None) -> PayloadCalibration:
    """Fit the torque offsets and the payload's centre of mass from static samples of known mass.

    Linear least squares over both joints' equilibrium (eq. 8 with the payload's weight at a point
    ``b`` of the bucket frame)::

        tau_T - G_T = o_T - m g h(R(theta) b)
        tau_L - G_L = o_L - m g (h(R(theta) b) + h(p_T) - h(p_L))

    Unknowns ``o_L, o_T, b_x, b_z``. Samples at one bucket angle fix only one direction of ``b``; the
    fit then keeps the prior's value along the other (it solves for the smallest change from the
    prior, ignoring directions weaker than :data:`FIT_RCOND`). Hold the bucket at several angles to
    fit both.

    Args:
        lift_rad, tilt_rad: (n,) measured angles, rad.
        lift_torque_nm, tilt_torque_nm: (n,) measured torques, N*m.
        mass_kg: (n,) known payload masses, kg.
        chassis_pitch_rad: (n,) or scalar chassis pitch, rad.
        prior: starting calibration (its gravity is kept); defaults to :class:`PayloadCalibration` ().

    Returns:
        The fitted calibration, with residuals and sample counts in ``fit``.

    Raises:
        ValueError: with fewer than 2 samples, or none with a payload.
    """
    prior = prior or PayloadCalibration()
    lift, tilt, tau_l, tau_t, mass = (np.asarray(a, dtype=float).reshape(-1) for a in
                                      (lift_rad, tilt_rad, lift_torque_nm, tilt_torque_nm, mass_kg))
    n = len(lift)
    if n < 2 or not all(len(a) == n for a in (tilt, tau_l, tau_t, mass)):
        raise ValueError(f"calibration needs at least 2 samples of equal length, got {n}")
    if not np.any(mass > 0):
        raise ValueError("calibration needs samples with a payload (mass_kg > 0) to fit the lever arm")
    pitch = np.broadcast_to(np.asarray(chassis_pitch_rad, dtype=float), lift.shape)
    g = prior.gravity_mps2
    up = up_in_chassis(pitch)
    theta = kinematics.bucket_angle(lift, tilt)
    # h(R(theta) b) = b_x * a_x + b_z * a_z
    a_x = horizontal(kinematics.pitch(np.array([1.0, 0.0]), theta), up)
    a_z = horizontal(kinematics.pitch(np.array([0.0, 1.0]), theta), up)
    span = horizontal(kinematics.bucket_joint_position(lift), up) - horizontal(kinematics.LIFT_JOINT_M, up)
    gravity = gravity_torques(lift, tilt, pitch, g)
    zeros, ones = np.zeros(n), np.ones(n)
    design = np.concatenate([
        np.stack([zeros, ones, -mass * g * a_x, -mass * g * a_z], axis=1),
        np.stack([ones, zeros, -mass * g * a_x, -mass * g * a_z], axis=1)])
    target = np.concatenate([tau_t - gravity[:, 1], tau_l - gravity[:, 0] + mass * g * span])
    start = np.array([prior.lift_offset_nm, prior.tilt_offset_nm, *prior.payload_com_in_bucket_m])
    # scale the columns so the minimum-norm correction weighs N*m and metres alike
    scale = np.linalg.norm(design, axis=0)
    scale[scale == 0] = 1.0
    step, _, rank, _ = np.linalg.lstsq(design / scale, target - design @ start, rcond=FIT_RCOND)
    solution = start + step / scale
    residual = target - design @ solution
    fitted = replace(prior, lift_offset_nm=float(solution[0]), tilt_offset_nm=float(solution[1]),
                     payload_com_in_bucket_m=(float(solution[2]), float(solution[3])))
    eq8 = mass_eq8(lift, tilt, tau_l, tau_t, fitted, pitch)
    eq4 = mass_eq4(lift, tilt, tau_t, fitted, pitch)
    fit = {
        "samples": int(n),
        "samples_with_payload": int(np.sum(mass > 0)),
        "rank": int(rank),
        "rms_residual_tilt_nm": float(np.sqrt(np.mean(residual[:n] ** 2))),
        "rms_residual_lift_nm": float(np.sqrt(np.mean(residual[n:] ** 2))),
        "eq8_max_abs_error_kg": float(np.max(np.abs(eq8 - mass))),
        "eq4_max_abs_error_kg": float(np.nanmax(np.abs(eq4 - mass))),
        "mass_range_kg": [float(mass.min()), float(mass.max())],
        "bucket_angle_range_rad": [float(theta.min()), float(theta.max())],
    }
    return replace(fitted, fit=fit)
