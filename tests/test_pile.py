"""The pile builder: the paper's 4-3-2 stack with the requested face slope."""

import numpy as np
import pytest

from autoscoop.core.config import PileConfig
from autoscoop.sim.pile import face_slope_deg, layer_rows, pile_layout


@pytest.mark.parametrize("angle", [25.0, 32.0, 40.0])
def test_face_slope_and_count(angle):
    centres = pile_layout(PileConfig(angle_deg=angle))
    assert len(centres) == 72
    assert face_slope_deg(centres, 0.034) == pytest.approx(angle, abs=1.0)
    assert centres[:, 0].min() == pytest.approx(0.034)  # toe at x = 0


def test_paper_stack_and_other_counts():
    assert layer_rows(72, 8) == [4, 3, 2]
    assert len(pile_layout(PileConfig(n_particles=50))) == 50


def test_no_two_particles_overlap_even_with_jitter():
    centres = pile_layout(PileConfig(), np.random.default_rng(0))
    gaps = np.linalg.norm(centres[:, None] - centres[None], axis=-1) + np.eye(len(centres))
    assert gaps.min() >= 2 * 0.034
