"""The bucket holds about 23 particles (7 kg +- 15 %) when filled until it overflows."""

import numpy as np

from autoscoop.core.config import ScoopConfig
from autoscoop.sim.capacity import CAPACITY_PARTICLES, capacity, fill_until_overflow

RATED_PARTICLES = 7.0 / 0.3


def test_bucket_holds_about_the_rated_load():
    finals = [capacity(fill_until_overflow(ScoopConfig(), seed=seed)) for seed in range(3)]
    mass = np.mean(finals) * 0.3
    assert 0.85 * 7.0 <= mass <= 1.15 * 7.0, f"capacity {finals} particles = {mass:.2f} kg, rated 7 kg +- 15 %"
    # the volumetric fill's capacity constant is this measurement (to the particle)
    assert abs(np.mean(finals) - CAPACITY_PARTICLES) <= 1.0, (finals, CAPACITY_PARTICLES)


def test_capacity_stops_when_drops_add_nothing():
    counts = fill_until_overflow(ScoopConfig(), max_particles=40, patience=3, seed=0)
    assert len(counts) < 40  # it stopped early: three drops in a row added nothing
    assert counts[-4] >= max(counts[-3:])
    assert capacity(counts) > 0.7 * RATED_PARTICLES


def test_capacity_ignores_a_heap_that_slides_off():
    assert capacity([1, 2, 3, 9, 4, 5, 5]) == 5
