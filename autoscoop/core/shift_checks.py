"""Checks of a shift's settings before anything is simulated (numpy only): each error names the key to change."""

from __future__ import annotations

import numpy as np

from autoscoop.core import kinematics
from autoscoop.core.config import ScoopConfig

RIM_CLEARANCE_M = 0.02
"""The tipped bucket's cutting edge must pass at least this far above the hopper's rim, m."""
HOPPER_WALL_M = 0.02
"""Thickness of the hopper's walls and floor, m."""
PILE_CLEARANCE_M = 0.05
"""The spotted hopper's outer far wall stays at least this far short of the pile's toe, m."""


def dump_edge_height_m() -> float:
    """Height of the cutting edge with the arm fully up and the bucket fully tipped down (the dump pose), m."""
    lift, tilt = kinematics.LIFT_RANGE_RAD[0], kinematics.TILT_RANGE_RAD[1]
    return float(kinematics.arm_pose(lift, tilt).tip[1])


def check_shift_config(config: ScoopConfig) -> None:
    """Refuse a shift that cannot work, before any simulation.

    Raises:
        ValueError: naming the key: a pile too small for one full scoop, a hopper whose rim the tipped bucket
            cannot clear, a hopper that would stand on the pile, or a randomised world.
    """
    shift, pile = config.shift, config.pile
    rated = config.reward.rated_load_kg
    pile_kg = shift.pile_particles * pile.particle_mass_kg
    if pile_kg < rated:
        raise ValueError(f"shift.pile_particles = {shift.pile_particles}: the pile holds {pile_kg:g} kg "
                         f"({pile.particle_mass_kg:g} kg each, pile.particle_mass_kg), less than one full scoop "
                         f"(reward.rated_load_kg = {rated:g} kg); give at least {int(np.ceil(rated / pile.particle_mass_kg))}")
    reach = dump_edge_height_m() - RIM_CLEARANCE_M
    if shift.hopper_height_m > reach:
        raise ValueError(f"shift.hopper_height_m = {shift.hopper_height_m:g} m: the hopper is out of reach; with the arm "
                         f"fully up the tipped bucket's edge is {dump_edge_height_m():.3f} m high, so the rim may be at "
                         f"most {reach:.3f} m")
    shortest = shift.hopper_length_m / 2 + HOPPER_WALL_M + PILE_CLEARANCE_M
    if shift.haul_distance_m < shortest:
        raise ValueError(f"shift.haul_distance_m = {shift.haul_distance_m:g} m: the hopper would stand on the pile; "
                         f"a hopper {shift.hopper_length_m:g} m long (shift.hopper_length_m) needs a haul distance of at "
                         f"least {shortest:.3f} m")
    if config.randomize.active:
        raise ValueError("randomize.preset: a shift runs in one world, the config's; set randomize.preset=none and "
                         "leave the randomize ranges empty")
