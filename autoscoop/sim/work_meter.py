"""The actuators' mechanical work and the wheels' slip, summed over physics steps (a substep observer of
:class:`autoscoop.sim.scene.ScoopSim`)."""

from __future__ import annotations

import mujoco
import numpy as np

from autoscoop.sim.scene import WHEEL_RADIUS_M, WHEELS

ACTUATORS = (*WHEELS, "lift", "tilt")
"""Every actuator of the loader: the four wheel motors, then the lift and tilt servos."""


class WorkMeter:
    """Sums, after each physics step: the actuators' positive mechanical work (force times velocity at each
    actuator, negative power, braking, counted as zero: a hydraulic or electric drive does not recover it),
    the distance the wheels rolled and the distance the chassis travelled along its heading.
    ``positive_work_by_actuator_j`` splits the work by actuator, in the order of :data:`ACTUATORS` (J).

    Args:
        model: the compiled scene.
        data: its state.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.model, self.data = model, data
        self._actuators = np.array([model.actuator(name).id for name in ACTUATORS], dtype=int)
        self._wheel_dofs = np.array([model.joint(name).dofadr[0] for name in WHEELS], dtype=int)
        self._root_dof = model.joint("root").dofadr[0]
        self._chassis = model.body("chassis").id
        self.reset()

    def reset(self) -> None:
        """Start the sums from zero."""
        self.positive_work_j = 0.0
        self.positive_work_by_actuator_j = np.zeros(len(ACTUATORS))
        self.wheel_travel_m = 0.0
        self.chassis_travel_m = 0.0

    def __call__(self) -> None:
        d, step = self.data, self.model.opt.timestep
        power = np.clip(d.actuator_force[self._actuators] * d.actuator_velocity[self._actuators], 0.0, None) * step
        self.positive_work_by_actuator_j += power
        self.positive_work_j += float(power.sum())
        self.wheel_travel_m += abs(float(d.qvel[self._wheel_dofs].mean())) * WHEEL_RADIUS_M * step
        heading = d.xmat[self._chassis].reshape(3, 3)[:, 0]
        self.chassis_travel_m += abs(float(d.qvel[self._root_dof:self._root_dof + 3] @ heading)) * step

    @property
    def slip(self) -> float:
        """Wheel slip: 1 - chassis travel / wheel travel (0: rolling without slip; nan before the wheels turn)."""
        return 1.0 - self.chassis_travel_m / self.wheel_travel_m if self.wheel_travel_m > 0 else float("nan")
