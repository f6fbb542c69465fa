"""How many particles the bucket holds: drop them in one at a time until it overflows.

The loader stands still in its carry pose (arm fully raised, bucket fully curled, so the mouth
faces up); particles fall one by one from above the middle of the mouth (between the top of the
back plate and the cutting edge), each at a random spot across its width, and settle.
The bucket is full when several drops in a row add nothing.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

import mujoco
import numpy as np

from autoscoop.core import kinematics
from autoscoop.core.config import ScoopConfig
from autoscoop.sim.scene import ScoopSim

HOLD_LIFT_RAD = kinematics.LIFT_RANGE_RAD[0]
HOLD_TILT_RAD = kinematics.TILT_RANGE_RAD[0]
"""Carry pose: arm fully raised, bucket fully curled."""
BUCKET_LENGTH_M = kinematics.TIP_FROM_TILT_JOINT_M
DROP_HEIGHT_FRACTION = 20 / 43
"""Height of each drop above the middle of the bucket's mouth, as a fraction of the bucket's length (about half)."""
DROP_SPREAD_FRACTION = 8 / 43
"""Largest offset of a drop along the mouth from its middle, as a fraction of the bucket's length (about a fifth)."""
DROP_HEIGHT_M = BUCKET_LENGTH_M * DROP_HEIGHT_FRACTION
DROP_SPREAD_M = BUCKET_LENGTH_M * DROP_SPREAD_FRACTION
SETTLE_PER_DROP_S = 0.75


def fill_until_overflow(config: ScoopConfig | None = None, max_particles: int = 40, patience: int = 6,
                        seed: int = 0) -> list[int]:
    """Drop particles into the held bucket; return the count inside after each drop.

    Args:
        config: scene configuration (particle size and mass, physics step); the pile itself is unused.
        max_particles: particles available to drop.
        patience: stop after this many drops in a row that did not raise the count.
        seed: seed of the drop positions.

    Returns:
        Counts of particles inside the bucket after each drop; see :func:`capacity`.
    """
    config = config or ScoopConfig()
    config = config.replace(pile=config.pile.replace(n_particles=max_particles, variants=1))
    sim = ScoopSim(config)
    m, d = sim.model, sim.data
    m.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)  # teleported particles must not stay asleep
    rng = np.random.default_rng(seed)
    mujoco.mj_resetData(m, d)
    tilt = HOLD_TILT_RAD
    sim.set_pose(-1.5, HOLD_LIFT_RAD, tilt)
    for i in range(max_particles):  # park every particle in a row far to the side
        sim.set_particle(i, np.array([2.0 + 0.1 * i, 3.0, config.pile.radius_m]))
    mujoco.mj_forward(m, d)
    mujoco.mj_step(m, d, nstep=int(0.5 / m.opt.timestep))
    mouth = kinematics.BUCKET_INSIDE_POLYGON_M[1:3].mean(axis=0)
    counts, best, stale = [], 0, 0
    for i in range(max_particles):
        above = sim.bucket_to_world(np.array([mouth[0], 0.0, mouth[1]]))
        y = rng.uniform(-0.8, 0.8) * kinematics.BUCKET_INNER_HALF_WIDTH_M
        sim.set_particle(i, above + np.array([rng.uniform(-DROP_SPREAD_M, DROP_SPREAD_M), y, DROP_HEIGHT_M]))
        mujoco.mj_step(m, d, nstep=int(SETTLE_PER_DROP_S / m.opt.timestep))
        counts.append(int(sim.particles_in_bucket().sum()))
        stale = 0 if counts[-1] > best else stale + 1
        best = max(best, counts[-1])
        if stale >= patience:
            break
    return counts


def capacity(counts: list[int]) -> int:
    """The most particles that stayed in the bucket over two drops in a row (a lucky heap that
    slides off with the next drop does not count)."""
    if len(counts) < 2:
        return counts[0] if counts else 0
    return max(min(a, b) for a, b in zip(counts, counts[1:]))


NOMINAL_RADIUS_M = ScoopConfig().pile.radius_m
"""Particle radius of the capacity measurement (``pile.radius_m``'s default for this machine), m."""
CAPACITY_PARTICLES = kinematics.MACHINE.bucket.capacity_particles
"""Particles of :data:`NOMINAL_RADIUS_M` the bucket holds heaped (the machine's ``bucket.capacity_particles``: for
the Komodo :func:`capacity` of :func:`fill_until_overflow` gave 24, 24 and 26 for seeds 0-2, mean 24.7);
``tests/test_capacity.py`` keeps it."""
CAPACITY_M3 = CAPACITY_PARTICLES * 4.0 / 3.0 * math.pi * NOMINAL_RADIUS_M**3
"""The bucket's heaped capacity as the solid volume of the particles it holds, m^3 (the Komodo's: about 4.1 L)."""


def volumetric_fill(particles: int, radius_m: float) -> float:
    """The particles' solid volume over the bucket's capacity (:data:`CAPACITY_M3`); loaders are rated by
    volume as well as by mass (light earth fills a bucket by volume before it reaches the rated mass)."""
    return particles * 4.0 / 3.0 * math.pi * radius_m**3 / CAPACITY_M3


MEASURE_SEEDS = (0, 1, 2)
"""Seeds of the drops that measure ``bucket.capacity_particles`` (``autoscoop machine check``)."""


def measure_capacity(seeds: tuple[int, ...] = MEASURE_SEEDS) -> dict[str, object]:
    """:func:`capacity` of :func:`fill_until_overflow` on each seed, with the nominal pile's particles of the
    process's machine: ``{"radius_m", "seeds", "counts", "mean"}``."""
    counts = [capacity(fill_until_overflow(seed=seed)) for seed in seeds]
    return {"radius_m": NOMINAL_RADIUS_M, "seeds": list(seeds), "counts": counts, "mean": sum(counts) / len(counts)}


def main(argv: list[str] | None = None) -> int:
    """Print :func:`measure_capacity` as JSON for the process's machine (``$AUTOSCOOP_MACHINE``)."""
    parser = argparse.ArgumentParser(description="measure the bucket's heaped capacity in particles of the "
                                                 "machine's nominal pile ($AUTOSCOOP_MACHINE)")
    parser.add_argument("--seeds", type=int, nargs="+", default=list(MEASURE_SEEDS))
    args = parser.parse_args(argv)
    print(json.dumps(measure_capacity(tuple(args.seeds))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
