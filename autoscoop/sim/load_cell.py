"""The robot's view of the payload in simulation: joint torques plus load-cell noise, turned into kilograms.

:mod:`autoscoop.core.payload` does the statics (numpy only); this module reads the simulator the way the
robot reads its sensors (potentiometer angles, actuator torques, IMU pitch), adds the load cell's
noise, and hands them to the estimator. The environment uses it when ``env.mass_source = torque``.

The robot's load cell samples far faster than the 4 Hz control loop, and a controller sees its
reading averaged over the control period. The sensor does the same: it averages the readings of
every physics step since the previous estimate (:class:`ReadingWindow`: the core's
:class:`~autoscoop.core.payload.ReadingAverage`, which the ROS controller uses too, fed by a substep
observer of :class:`ScoopSim`). That matters: particles resting on the servo-held bucket rattle, and
single readings swing by a kilogram or more around the right mean.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from autoscoop.core.config import ScoopConfig
from autoscoop.core.payload import (
    PayloadCalibration,
    PayloadEstimator,
    PayloadReading,
    ReadingAverage,
    reported_mass_kg,
)
from autoscoop.sim.scene import ScoopSim


def chassis_pitch_rad(sim: ScoopSim) -> float:
    """The chassis pitch an IMU reports, rad; positive nose down (about +y, like the arm joints)."""
    _, rotation = sim.chassis_pose
    # world up expressed in the chassis frame is the rotation's last row; its x-z part is (-sin, cos)(pitch)
    return float(math.atan2(-rotation[2, 0], rotation[2, 2]))


def instant_reading(sim: ScoopSim) -> PayloadReading:
    """The noise-free readings at this physics step."""
    return PayloadReading(lift_rad=sim.lift_rad, tilt_rad=sim.tilt_rad, lift_torque_nm=sim.lift_torque_nm,
                          tilt_torque_nm=sim.tilt_torque_nm, chassis_pitch_rad=chassis_pitch_rad(sim))


class ReadingWindow:
    """Averages the readings of every physics step since it was last taken (attached to ``sim`` at once).

    A :class:`~autoscoop.core.payload.ReadingAverage` fed by a substep observer of the sim.
    """

    def __init__(self, sim: ScoopSim) -> None:
        self.sim = sim
        self.average = ReadingAverage()
        sim.add_substep_observer(self._accumulate)

    def _accumulate(self) -> None:
        self.average.add(instant_reading(self.sim))

    def take(self) -> PayloadReading:
        """The mean since the last call (the instantaneous reading when no step was taken), then start over."""
        mean = self.average.take()
        return instant_reading(self.sim) if mean is None else mean

    @property
    def attached(self) -> bool:
        """Whether the window is still averaging its sim's physics steps."""
        return self._accumulate in self.sim.substep_observers

    def detach(self) -> None:
        """Stop averaging (with no other observer, the sim steps in one C call again)."""
        self.sim.remove_substep_observer(self._accumulate)


class TorqueMassSensor:
    """Payload mass from the simulated joint torques, as the robot would estimate it.

    Args:
        estimator: the calibrated estimator (eq. 8 by default).
        noise_nm: standard deviation of the Gaussian noise on each torque reading the controller
            gets (one per control step, after averaging), N*m.
        rng: noise source.
        use_imu_pitch: correct for the chassis pitch (the robot has an IMU); else gravity along chassis -z.
        average: average the readings over the physics steps since the previous estimate.
        clip_negative: report 0 instead of negative masses (noise on an empty bucket), as a
            particle count never goes below zero.
        offset_nm: constant offsets of the (lift, tilt) torque readings, N*m (a miscalibrated load
            cell; a randomised world draws them). Reports follow :func:`autoscoop.core.payload.reported_mass_kg`,
            as the ROS node's do (an undefined estimate keeps the previous report).
    """

    def __init__(self, estimator: PayloadEstimator | None = None, noise_nm: float = 0.0,
                 rng: np.random.Generator | None = None, use_imu_pitch: bool = True, average: bool = True,
                 clip_negative: bool = True, offset_nm: tuple[float, float] = (0.0, 0.0)) -> None:
        if not (math.isfinite(noise_nm) and noise_nm >= 0.0):
            raise ValueError(f"load-cell noise must be a finite number >= 0 N*m, got {noise_nm}")
        if len(offset_nm) != 2 or not all(math.isfinite(v) for v in offset_nm):
            raise ValueError(f"load-cell offset must be two finite numbers (lift, tilt) N*m, got {offset_nm}")
        self.offset_nm = (float(offset_nm[0]), float(offset_nm[1]))
        self.estimator = estimator or PayloadEstimator()
        self.noise_nm = float(noise_nm)
        self.rng = rng if rng is not None else np.random.default_rng()
        self.use_imu_pitch = use_imu_pitch
        self.average = average
        self.clip_negative = clip_negative
        self._window: ReadingWindow | None = None
        self._reported_kg = 0.0

    @classmethod
    def for_env(cls, config: ScoopConfig, rng: np.random.Generator,
                calibration: PayloadCalibration | str | Path | None = None,
                offset_nm: tuple[float, float] = (0.0, 0.0)) -> TorqueMassSensor:
        """The sensor the environment uses: eq. 8, control-period averages, noise ``env.load_cell_noise_nm``
        on each average plus ``sensor.torque_noise_nm`` on each physics step's sample (averaged with them:
        divided by the square root of the steps per control period; the two added in quadrature).

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
        noise = config.env.load_cell_noise_nm
        if config.sensor.torque_noise_nm:
            noise = math.hypot(noise, config.sensor.torque_noise_nm / math.sqrt(config.substeps))
        return cls(PayloadEstimator(calibration or PayloadCalibration()), noise, child, offset_nm=offset_nm)

    def detach(self) -> None:
        """Stop averaging the sim's physics steps (an episode ended; the environment makes a new sensor)."""
        if self._window is not None:
            self._window.detach()
            self._window = None

    def read(self, sim: ScoopSim) -> PayloadReading:
        """The readings the estimate uses, noise included; the first call attaches the averaging window."""
        if self.average:
            if self._window is None or self._window.sim is not sim or not self._window.attached:
                self._window = ReadingWindow(sim)
            clean = self._window.take()
        else:
            clean = instant_reading(sim)
        noise = self.rng.normal(0.0, self.noise_nm, 2) if self.noise_nm > 0 else np.zeros(2)
        return PayloadReading(lift_rad=clean.lift_rad, tilt_rad=clean.tilt_rad,
                              lift_torque_nm=clean.lift_torque_nm + self.offset_nm[0] + float(noise[0]),
                              tilt_torque_nm=clean.tilt_torque_nm + self.offset_nm[1] + float(noise[1]),
                              chassis_pitch_rad=clean.chassis_pitch_rad if self.use_imu_pitch else 0.0)

    def estimate(self, sim: ScoopSim) -> float:
        """Payload mass now, kg."""
        mass = self.estimator.mass_kg(self.read(sim))
        self._reported_kg = reported_mass_kg(mass, self._reported_kg, 0.0 if self.clip_negative else -math.inf)
        return self._reported_kg
