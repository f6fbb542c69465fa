"""The hopper a shift's loader dumps into: an open box on the ground, a MuJoCo mocap body added to the scene only
for a shift (:class:`autoscoop.sim.shift_sim.ShiftSim`).

Frame: the world (pile) frame, x forward from the pile's toe, y left, z up from the ground, metres. The
hopper's position is the centre of its inner floor, on the ground; it is parked far from the pile until it is
spotted, as a truck backs in between the loader and the face in I-cycle loading.
"""

from __future__ import annotations

import mujoco
import numpy as np

from autoscoop.core.config import ShiftConfig
from autoscoop.core.shift_checks import HOPPER_WALL_M

HOPPER_BODY = "hopper"
PARKED_POSITION_M = (-8.0, -6.0, 0.0)
"""Where the hopper waits while it is not spotted: far from the pile, the loader and kept particles."""
HEAP_ABOVE_RIM_M = 0.25
"""Particles heaped this far above the rim, within the hopper's inner footprint, are still in it, m."""


def add_hopper(spec: mujoco.MjSpec, shift: ShiftConfig) -> None:
    """Add the hopper to a scene's spec: a floor and four walls of a mocap body named ``hopper``.

    Its geoms collide as the ground does (with the particles and the loader) and carry the contact time
    constant of the scene's other geoms.
    """
    body = spec.worldbody.add_body(name=HOPPER_BODY, pos=list(PARKED_POSITION_M), mocap=True)
    half_length, half_width, height = shift.hopper_length_m / 2, shift.hopper_width_m / 2, shift.hopper_height_m
    t = HOPPER_WALL_M
    boxes = {
        "floor": ([half_length + t, half_width + t, t / 2], [0.0, 0.0, -t / 2]),
        "near_wall": ([t / 2, half_width + t, height / 2], [-half_length - t / 2, 0.0, height / 2]),
        "far_wall": ([t / 2, half_width + t, height / 2], [half_length + t / 2, 0.0, height / 2]),
        "left_wall": ([half_length, t / 2, height / 2], [0.0, half_width + t / 2, height / 2]),
        "right_wall": ([half_length, t / 2, height / 2], [0.0, -half_width - t / 2, height / 2]),
    }
    solref = next(iter(spec.geoms)).solref if spec.geoms else None
    for name, (size, pos) in boxes.items():
        geom = body.add_geom(name=f"hopper_{name}", type=mujoco.mjtGeom.mjGEOM_BOX, size=size, pos=pos,
                             contype=1, conaffinity=0, condim=3, rgba=[0.35, 0.4, 0.5, 1.0])
        if solref is not None:
            geom.solref = list(solref)


def inside_hopper(positions_m: np.ndarray, hopper_position_m: np.ndarray, shift: ShiftConfig) -> np.ndarray:
    """Which particle centres lie within the hopper's inner footprint, from its floor up to a heap above the rim.

    Args:
        positions_m: (n, 3) particle centres in the world frame, m.
        hopper_position_m: (3,) the hopper's inner floor centre in the world frame, m.
        shift: the hopper's size.

    Returns:
        (n,) boolean mask.
    """
    offset = np.asarray(positions_m, dtype=float) - np.asarray(hopper_position_m, dtype=float)
    return ((np.abs(offset[:, 0]) <= shift.hopper_length_m / 2) & (np.abs(offset[:, 1]) <= shift.hopper_width_m / 2)
            & (offset[:, 2] >= 0.0) & (offset[:, 2] <= shift.hopper_height_m + HEAP_ABOVE_RIM_M))
