"""The scene of a loader's shift: the scooping scene with a hopper, a pile that keeps every scoop's mark, and
the particles the hopper received kept apart.

World frame as in :mod:`autoscoop.sim.scene`: x forward from the pile's toe, y left, z up, metres. At each
scoop's start the whole world (the loader and every particle not yet delivered) is moved along x so that the
pile's toe is at x = 0 again: the ground is flat and endless, so nothing physical changes, and the scoop sees
the frame it always does (its terminal point ``reward.terminal_dx_m`` past the toe). :attr:`ShiftSim.toe_shift_m`
keeps how far the toe has retreated since the shift's start.
"""

from __future__ import annotations

import functools

import mujoco
import numpy as np

from autoscoop.core import kinematics
from autoscoop.core.config import PileConfig, ScoopConfig
from autoscoop.core.shift_accounting import ParticleAccount, account, toe_x_m, touching_cluster
from autoscoop.sim.hopper import HOPPER_BODY, PARKED_POSITION_M, add_hopper, inside_hopper
from autoscoop.sim.scene import ScoopSim, compile_scene

DELIVERED_X_M, DELIVERED_Y_M = -6.0, -3.0
"""Where delivered particles are kept (rows along -x from here, the next row further along -y, at rest on the
ground): the load left with its truck."""
DELIVERED_SPACING_RADII = 3.0
"""Centres of kept particles this many radii apart."""
DELIVERED_PER_ROW = 40
"""Kept particles per row."""
REACH_BEHIND_TOE_M = 0.6
"""How far behind the toe a scoop can move the pile (the bucket reaches about 0.4 m past it), m."""
BACK_OFF_M = 0.6
"""How far :meth:`ShiftSim.clear_for_next_scoop` sets the loader back from where its scoop ended while the pile
settles, m."""
BETWEEN_SCOOPS_S = 2.0
"""How long the pile settles between two scoops of :meth:`ShiftSim.clear_for_next_scoop`, simulated s."""
HELD_DAMPING_NS_M = 2000.0
"""Damping of the sliding motion of particles farther behind the toe than :data:`REACH_BEHIND_TOE_M`, N*s/m.

A pile of rolling spheres creeps on once awake (only their spin is damped), and every scoop wakes the whole pile;
gravel farther back does not move. This damping holds those particles in place (a 0.3 kg particle that lost its
support sinks at about 1.5 mm/s) while they still bear and push on the particles in reach."""


class ShiftSim(ScoopSim):
    """The scooping scene of :class:`ScoopSim` with a hopper; its pile carries over from one scoop to the next.

    The first :meth:`reset` after :meth:`start_shift` settles a fresh pile as :class:`ScoopSim` does; every later
    one keeps the pile and the loader where they are and moves the world so that the toe is at x = 0.

    Args:
        config: the shift's scene (``pile.n_particles`` the shift's pile; ``shift.*`` the hopper).
    """

    def __init__(self, config: ScoopConfig) -> None:
        super().__init__(config)
        self._hopper = self.model.body(HOPPER_BODY).mocapid[0]
        self._root_x = self.model.joint("root").qposadr[0]
        self._particle_x = np.array([self.model.joint(f"particle_{i:03d}").qposadr[0]
                                     for i in range(self.n_particles)], dtype=int)
        self._particle_dofs = np.array([self.model.joint(f"particle_{i:03d}").dofadr[0]
                                        for i in range(self.n_particles)], dtype=int)
        self._free_damping = self.model.dof_damping[self._particle_dofs[:, None] + np.arange(3)].copy()
        particle_bodies = {self.model.body(f"particle_{i:03d}").id for i in range(self.n_particles)}
        self._loader_dofs = np.flatnonzero([body not in particle_bodies for body in self.model.dof_bodyid])
        self.start_shift()

    def compile_model(self, config: ScoopConfig) -> mujoco.MjModel:
        """The scooping scene with the hopper (:func:`autoscoop.sim.hopper.add_hopper`)."""
        return compile_scene(config, functools.partial(add_hopper, shift=config.shift))

    def start_shift(self) -> None:
        """The next :meth:`reset` starts a new shift on a freshly settled pile; nothing is delivered yet."""
        self.delivered = np.zeros(self.n_particles, dtype=bool)
        self.toe_shift_m = 0.0
        self._continuing = False

    def reset(self, rng: np.random.Generator | None = None, *, pile: PileConfig | None = None,
              start_gap_m: float | None = None, prescoop_particles: int | None = None) -> None:
        """A shift's first scoop: a settled pile as :meth:`ScoopSim.reset` gives it. A later one: the pile and the
        loader as the last cycle left them, the world moved so that the toe is at x = 0, the clock restarted."""
        if not self._continuing:
            super().reset(rng, pile=pile, start_gap_m=start_gap_m, prescoop_particles=prescoop_particles)
            self._continuing = True
        else:
            self.recentre_on_toe()
            self.restart_clock()
        self.hold_pile_out_of_reach()

    @property
    def continuing(self) -> bool:
        """Whether the next :meth:`reset` keeps the pile as the last scoop left it (a shift has begun)."""
        return self._continuing

    def clear_for_next_scoop(self, rng: np.random.Generator) -> bool:
        """Between two scoops without the scripted carry (training on the changing pile): what the scoop lifted
        leaves, the pile settles, and the loader stands at its start pose before the new toe, at rest.

        The particles in the bucket, and any others off the pile and above the ground (heaped on the bucket, still
        falling), are taken away as delivered. So is anything off the pile in front of the toe, which the loader
        would otherwise be set down on (the shift's return pushes such particles along). The loader is set
        :data:`BACK_OFF_M` back with its arm at the start pose while the pile settles for :data:`BETWEEN_SCOOPS_S`;
        then the world is moved so that the toe is at x = 0, and the loader's tip is put ``robot.start_gap_m``
        (with up to ``robot.start_gap_jitter_m`` of jitter) short of it. The episode clock restarts.

        Args:
            rng: draws the start gap's jitter.

        Returns:
            Whether a pile is left on the loader's path after the settling; when none is, the world is not moved
            and the loader stays set back (start a fresh pile).
        """
        cfg, radius = self.config, self.config.pile.radius_m
        positions = self.particle_positions
        off_pile = ~self.delivered & ~self.pile_mask()
        lifted = self.particles_in_bucket() | (off_pile & (positions[:, 2] > 2.0 * radius))
        self._keep_delivered(np.flatnonzero(lifted & ~self.delivered))
        lift, tilt = cfg.robot.start_lift_rad, cfg.robot.start_tilt_rad
        self.set_pose(float(self.chassis_pose[0][0]) - BACK_OFF_M, lift, tilt)
        self._stop_loader()
        self.command(0.0, 0.0, 0.0)
        mujoco.mj_forward(self.model, self.data)
        self.step(int(round(BETWEEN_SCOOPS_S / self.model.opt.timestep)))
        toe = self.toe_x_m()
        if not np.isfinite(toe):
            return False
        self.recentre_on_toe()
        positions = self.particle_positions
        in_front = ~self.delivered & ~self.pile_mask() & (positions[:, 0] < 0.0)
        self._keep_delivered(np.flatnonzero(in_front))
        jitter = cfg.robot.start_gap_jitter_m
        self.set_start_pose(cfg.robot.start_gap_m + (float(rng.uniform(-jitter, jitter)) if jitter > 0 else 0.0))
        self._stop_loader()
        mujoco.mj_forward(self.model, self.data)
        self.hold_pile_out_of_reach()
        self.restart_clock()
        return True

    def _stop_loader(self) -> None:
        """Zero the velocities of the loader's joints (chassis, wheels, arm and bucket)."""
        self.data.qvel[self._loader_dofs] = 0.0

    # ---------------------------------------------------------------- the pile
    def pile_mask(self) -> np.ndarray:
        """(n,) the particles on the pile now (:func:`autoscoop.core.shift_accounting.touching_cluster`)."""
        free = ~self.delivered & ~self.particles_in_bucket() & np.all(np.isfinite(self.particle_positions), axis=1)
        return touching_cluster(self.particle_positions, self.config.pile.radius_m, free)

    def toe_x_m(self) -> float:
        """The pile's toe on the loader's path now (within the bucket's width of y = 0), world x, m."""
        return toe_x_m(self.particle_positions, self.config.pile.radius_m, self.pile_mask(), self.pile_angle_deg,
                       kinematics.BUCKET_INNER_HALF_WIDTH_M)

    def hold_pile_out_of_reach(self) -> None:
        """Damp the sliding of particles more than :data:`REACH_BEHIND_TOE_M` behind the toe (x = 0 at a scoop's
        start) by :data:`HELD_DAMPING_NS_M`; those nearer move freely."""
        held = self.particle_positions[:, 0] > REACH_BEHIND_TOE_M
        for axis in range(3):  # the first three degrees of freedom of a particle slide along x, y, z
            self.model.dof_damping[self._particle_dofs + axis] = np.where(held, HELD_DAMPING_NS_M,
                                                                          self._free_damping[:, axis])

    def recentre_on_toe(self) -> float:
        """Move the loader and every particle not delivered along x so that the toe is at x = 0; returns the move, m."""
        toe = self.toe_x_m()
        if not np.isfinite(toe):
            return 0.0
        moving = self._particle_x[~self.delivered]
        self.data.qpos[moving] -= toe
        self.data.qpos[self._root_x] -= toe
        mujoco.mj_kinematics(self.model, self.data)
        self.toe_shift_m += toe
        return toe

    def align_with_pile(self) -> tuple[float, float]:
        """Put the loader, at rest, back on the pile's centre line (y = 0) facing +x, where it is along x: a driver
        steers a skid-steer back after the pile pushed it aside (the scoop's drive command cannot steer).

        Returns:
            The loader's sideways offset (m) and heading (deg) before the correction.
        """
        position, rotation = self.chassis_pose
        offset_m, heading_deg = float(position[1]), float(np.degrees(np.arctan2(rotation[1, 0], rotation[0, 0])))
        self.set_pose(float(position[0]), self.lift_rad, self.tilt_rad)
        root_dof = self.model.joint("root").dofadr[0]
        self.data.qvel[root_dof:root_dof + 6] = 0.0
        mujoco.mj_forward(self.model, self.data)
        return offset_m, heading_deg

    # ---------------------------------------------------------------- the hopper
    @property
    def hopper_position_m(self) -> np.ndarray:
        """The hopper's inner floor centre in the world frame, (3,) m."""
        return self.data.mocap_pos[self._hopper].copy()

    def spot_hopper(self, centre_x_m: float) -> None:
        """Stand the hopper with its centre at world x ``centre_x_m`` on the loader's path (y = 0)."""
        self.data.mocap_pos[self._hopper] = [centre_x_m, 0.0, 0.0]
        mujoco.mj_kinematics(self.model, self.data)

    def particles_in_hopper(self) -> np.ndarray:
        """(n,) particles inside the hopper now (not those already delivered)."""
        inside = inside_hopper(self.particle_positions, self.hopper_position_m, self.config.shift)
        return inside & ~self.delivered

    def deliver(self) -> int:
        """Count the particles in the hopper as delivered, keep them apart (the truck leaves with them) and park the
        hopper away from the pile; returns how many were delivered."""
        received = np.flatnonzero(self.particles_in_hopper())
        self._keep_delivered(received)
        self.data.mocap_pos[self._hopper] = PARKED_POSITION_M
        mujoco.mj_forward(self.model, self.data)
        return len(received)

    def _keep_delivered(self, indices: np.ndarray) -> None:
        """Count particles ``indices`` as delivered and lay them, at rest, in the rows where delivered ones are kept."""
        radius = self.config.pile.radius_m
        spacing = DELIVERED_SPACING_RADII * radius
        kept = int(self.delivered.sum())
        for k, index in enumerate(indices):
            row, place = divmod(kept + k, DELIVERED_PER_ROW)
            self.set_particle(int(index), np.array([DELIVERED_X_M - spacing * place, DELIVERED_Y_M - spacing * row, radius]))
        self.delivered[indices] = True

    def delivered_kept(self) -> np.ndarray:
        """(n,) particles lying, at rest on the ground, where delivered particles are kept."""
        positions, radius = self.particle_positions, self.config.pile.radius_m
        return (positions[:, 1] <= DELIVERED_Y_M + radius) & (positions[:, 0] <= DELIVERED_X_M + radius) \
            & (np.abs(positions[:, 2] - radius) <= radius)

    def account(self) -> ParticleAccount:
        """Where every particle is now: pile, bucket, delivered, spilled (or unaccounted for)."""
        return account(self.particle_positions, self.config.pile.radius_m, self.particles_in_bucket(),
                       self.delivered, self.delivered_kept())
