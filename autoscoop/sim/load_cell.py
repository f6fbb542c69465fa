"""The robot's view of the payload in simulation: joint torques plus load-cell noise, turned into kilograms.

:mod:`autoscoop.payload` does the statics (numpy only); this module reads the simulator the way the
robot reads its sensors (potentiometer angles, actuator torques, IMU pitch), adds the load cell's
noise, and hands them to the estimator. The environment uses it when ``env.mass_source = torque``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from autoscoop.config import ScoopConfig
from autoscoop.payload import PayloadCalibration, PayloadEstimator
from autoscoop.sim.scene import ScoopSim


@dataclass(frozen=True)
class LoadCellReading:
    """One set of the robot's readings for the payload estimate.

    Attributes:
        lift_rad: lift angle, rad.
        tilt_rad: tilt angle, rad.
        lift_torque_nm: lift actuator torque (noise included), N*m.
        tilt_torque_nm: tilt actuator torque (noise included), N*m.
        chassis_pitch_rad: chassis pitch (IMU), rad, positive nose down.
    """

    lift_rad: float
    tilt_rad: float
    lift_torque_nm: float
    tilt_torque_nm: float
    chassis_pitch_rad: float


def chassis_pitch_rad(sim: ScoopSim) -> float:
    """The chassis pitch an IMU reports, rad; positive nose down (about +y, like the arm joints)."""
    _, rotation = sim.chassis_pose
    # world up expressed in the chassis frame is the rotation's last row; its x-z part is (-sin, cos)(pitch)
    return float(math.atan2(-rotation[2, 0], rotation[2, 2]))


class TorqueMassSensor:
    """Payload mass from the simulated joint torques, as the robot would estimate it.

    Args:
        estimator: the calibrated estimator (eq. 8 by default).
        noise_nm: standard deviation of the Gaussian noise added to each torque reading, N*m.
        rng: noise source.
        use_imu_pitch: correct for the chassis pitch (the robot has an IMU); else gravity along chassis -z.
        clip_negative: report 0 instead of negative masses (noise on an empty bucket), as a
            particle count never goes below zero.
    """

    def __init__(self, estimator: PayloadEstimator | None = None, noise_nm: float = 0.0,
                 rng: np.random.Generator | None = None, use_imu_pitch: bool = True,
                 clip_negative: bool = True) -> None:
        if not (noise_nm >= 0.0 and math.isfinite(noise_nm)):
            raise ValueError(f"load-cell noise must be a finite number >= 0 N*m, got {noise_nm}")
        self.estimator = estimator or PayloadEstimator()
        self.noise_nm = float(noise_nm)
        self.rng = rng if rng is not None else np.random.default_rng()
        self.use_imu_pitch = use_imu_pitch
        self.clip_negative = clip_negative

    @classmethod
    def for_env(cls, config: ScoopConfig, rng: np.random.Generator,
                calibration: PayloadCalibration | str | Path | None = None) -> "TorqueMassSensor":
        """The sensor the environment uses: eq. 8, noise ``env.load_cell_noise_nm``.

        The noise comes from a child of ``rng`` (one draw), so episodes with the same seed lay out the
        same pile whichever mass source is used.

        Args:
            config: the scene's config.
            rng: the environment's generator.
            calibration: a calibration or the path of its YAML; default: the nominal one (zero
                offsets), which fits the simulator because its link masses are the estimator's.
        """
        if isinstance(calibration, (str, Path)):
            calibration = PayloadCalibration.load(calibration)
        child = np.random.default_rng(int(rng.integers(2**63)))
        return cls(PayloadEstimator(calibration or PayloadCalibration()), config.env.load_cell_noise_nm, child)

    def read(self, sim: ScoopSim) -> LoadCellReading:
        """The readings the estimate uses, torque noise included."""
        noise = self.rng.normal(0.0, self.noise_nm, 2) if self.noise_nm > 0 else np.zeros(2)
        return LoadCellReading(sim.lift_rad, sim.tilt_rad, sim.lift_torque_nm + float(noise[0]),
                               sim.tilt_torque_nm + float(noise[1]),
                               chassis_pitch_rad(sim) if self.use_imu_pitch else 0.0)

    def estimate(self, sim: ScoopSim) -> float:
        """Payload mass now, kg."""
        r = self.read(sim)
        mass = self.estimator.mass_kg(r.lift_rad, r.tilt_rad, r.lift_torque_nm, r.tilt_torque_nm, r.chassis_pitch_rad)
        if not math.isfinite(mass):
            return 0.0
        return max(mass, 0.0) if self.clip_negative else mass
