"""Layout of the particle pile, numpy only.

Frame ("pile frame" = world): x forward from the pile's toe (the front of the first particle
touching the ground), y left, z up from the ground; metres.

The paper stacks 72 spheres in three layers of 4, 3 and 2 rows (8 across). We keep that stack and
set its face slope exactly: rows within a layer are ``s = 4 r cos(angle)`` apart and each upper row
rests in the gap between two rows below, ``h = 2 r sin(angle)`` higher, so the line through the
layers' front particles rises at ``angle``. At 60 deg the rows touch (close packing); a shallower
pile has gaps narrower than a particle, so nothing falls through. Other particle counts fill
layers of b, b-1, ... 1 rows, bottom first, front to back.
"""

from __future__ import annotations

import math

import numpy as np

from autoscoop.core.config import PileConfig

GAP_M = 0.0005
"""Clearance added between neighbours so no two particles start in contact overlap."""


def layer_rows(n_particles: int, across: int, max_layers: int = 0) -> list[int]:
    """Rows in each layer, bottom first: the smallest pyramid b, b-1, ... that holds the particles; with
    ``max_layers`` (0: no limit), its lowest ``max_layers`` layers only, the base as long as they need (a long pile)."""
    rows_needed = math.ceil(n_particles / across)

    def holds(base: int) -> int:
        layers = min(base, max_layers) if max_layers else base
        return sum(base - k for k in range(layers))

    base = 1
    while holds(base) < rows_needed:
        base += 1
    rows, left = [], rows_needed
    for k in range(min(base, max_layers) if max_layers else base):
        take = min(base - k, left)
        if take <= 0:
            break
        rows.append(take)
        left -= take
    return rows


def pile_layout(pile: PileConfig, rng: np.random.Generator | None = None) -> np.ndarray:
    """Particle centres in the pile frame.

    Args:
        pile: pile configuration (angle, count, radius, rows across, jitter).
        rng: source of the small random jitter in x and y; ``None`` gives the exact layout.

    Returns:
        (n_particles, 3) array of centres, metres.
    """
    r = pile.radius_m + GAP_M / 2
    angle = math.radians(pile.angle_deg)
    row_spacing = 4 * r * math.cos(angle)
    layer_height = 2 * r * math.sin(angle)
    ys = (np.arange(pile.across) - (pile.across - 1) / 2) * 2 * r
    amp = _jitter_amplitude(pile, row_spacing) if rng is not None else 0.0
    # two neighbours may shift toward each other by up to 2 amp in x; lifting each layer by
    # 2 amp / tan(angle) keeps them clear of the layer below
    clearance = GAP_M + 2 * amp / math.tan(angle)
    centres = []
    for k, n_rows in enumerate(layer_rows(pile.n_particles, pile.across, pile.max_layers)):
        x0 = pile.radius_m + k * row_spacing / 2
        z = pile.radius_m + k * (layer_height + clearance)
        for j in range(n_rows):
            for y in ys:
                if len(centres) < pile.n_particles:
                    centres.append((x0 + j * row_spacing, y, z))
    out = np.array(centres, dtype=float)
    if amp > 0:
        out[:, 0] += rng.uniform(-amp, amp, size=len(out))
        out[:, 1] += rng.uniform(-GAP_M / 2, GAP_M / 2, size=len(out))  # neighbours across touch
    return out


def _jitter_amplitude(pile: PileConfig, row_spacing: float) -> float:
    """Largest x-jitter that keeps neighbours in a row apart (half the gap between rows)."""
    return min(pile.jitter_m, (row_spacing - 2 * pile.radius_m) / 2)


def face_slope_deg(centres: np.ndarray, radius_m: float) -> float:
    """Mean slope of the pile's face: least-squares line through each layer's front particle, degrees."""
    z_levels = np.round((centres[:, 2] - radius_m) / (radius_m * 0.5))
    fronts = []
    for level in np.unique(z_levels):
        layer = centres[z_levels == level]
        fronts.append((layer[:, 0].min(), layer[:, 2].mean()))
    if len(fronts) < 2:
        return float("nan")
    x, z = np.array(fronts).T
    slope = np.polyfit(x, z, 1)[0]
    return float(math.degrees(math.atan(slope)))
