"""Where every particle of a shift's pile is: on the pile, in the bucket, delivered, or spilled (numpy only).

Frame: the world (pile) frame, x forward from the pile's toe, y left, z up from the ground, metres.

The pile is the largest cluster of touching particles outside the bucket that were not delivered: two
particles touch when their centres are at most :data:`TOUCH_FACTOR` diameters apart. A particle that fell
off the bucket onto the pile's face is on the pile again; one lying apart from it is spilled. Each group
is found by its own test, so a particle that fits none (fallen through the ground, flown off, not finite)
or, as delivered, is not where delivered particles are kept, is counted as unaccounted for.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TOUCH_FACTOR = 1.15
"""Centres at most this many diameters apart count as touching (resting particles press slightly apart)."""
WORLD_HALF_SIZE_M = 20.0
"""A particle farther than this from the origin in x or y has left the world, m."""


@dataclass(frozen=True)
class ParticleAccount:
    """One moment's count of a shift's particles (boolean masks over the particles, each of length n).

    Attributes:
        pile: on the pile (the largest touching cluster outside the bucket).
        bucket: inside the bucket's volume.
        delivered: delivered to the hopper (and kept where delivered particles are).
        spilled: elsewhere in the world, apart from the pile.
        unaccounted: in none of the groups above.
    """

    pile: np.ndarray
    bucket: np.ndarray
    delivered: np.ndarray
    spilled: np.ndarray
    unaccounted: np.ndarray

    def counts(self) -> dict[str, int]:
        """Particles in each group, by name."""
        return {name: int(getattr(self, name).sum()) for name in ("pile", "bucket", "delivered", "spilled",
                                                                  "unaccounted")}

    def balanced(self) -> bool:
        """Whether every particle is in exactly one group and none is unaccounted for."""
        groups = np.stack([self.pile, self.bucket, self.delivered, self.spilled, self.unaccounted])
        return bool(np.all(groups.sum(axis=0) == 1) and not self.unaccounted.any())


def touching_cluster(positions_m: np.ndarray, radius_m: float, candidates: np.ndarray) -> np.ndarray:
    """The largest cluster of touching particles among ``candidates``.

    Args:
        positions_m: (n, 3) particle centres, m.
        radius_m: particle radius, m.
        candidates: (n,) mask of the particles that may belong.

    Returns:
        (n,) mask of the cluster (all false when there are no candidates).
    """
    index = np.flatnonzero(candidates)
    cluster = np.zeros(len(positions_m), dtype=bool)
    if not len(index):
        return cluster
    points = positions_m[index]
    offsets = points[:, None, :] - points[None, :, :]
    touching = np.einsum("ijk,ijk->ij", offsets, offsets) <= (2 * radius_m * TOUCH_FACTOR) ** 2
    label = np.full(len(index), -1)
    for seed in range(len(index)):
        if label[seed] >= 0:
            continue
        label[seed], frontier = seed, [seed]
        while frontier:
            neighbours = np.flatnonzero(touching[frontier].any(axis=0) & (label < 0))
            label[neighbours] = seed
            frontier = list(neighbours)
    largest = np.bincount(label).argmax()
    cluster[index[label == largest]] = True
    return cluster


FACE_HEIGHT_RADII = 2.5
"""The face is found where the pile first stands this many particle radii high (two layers): a particle or two
left lying in front of it do not make a toe."""


def toe_x_m(positions_m: np.ndarray, radius_m: float, pile: np.ndarray, angle_deg: float,
            path_half_width_m: float) -> float:
    """The pile's toe on the loader's path, world x, m: where its face, sloping at ``angle_deg``, meets the ground.

    Only the pile's particles within ``path_half_width_m`` of the path (y = 0) count: the bucket cuts a channel,
    and what it leaves at the sides is not the face it meets. The face is the foremost point at which the pile's
    top reaches :data:`FACE_HEIGHT_RADII` radii; the toe lies that height's run of the slope in front of it. A pile
    lower than that everywhere has its toe at the front of its foremost particle.
    """
    on_pile = positions_m[pile & (np.abs(positions_m[:, 1]) <= path_half_width_m)]
    if not len(on_pile):
        return float("nan")
    face_height = FACE_HEIGHT_RADII * radius_m
    high = on_pile[on_pile[:, 2] + radius_m >= face_height]
    if not len(high):
        return float(on_pile[:, 0].min() - radius_m)
    return float(high[:, 0].min() - radius_m - face_height / np.tan(np.radians(angle_deg)))


def account(positions_m: np.ndarray, radius_m: float, in_bucket: np.ndarray, delivered: np.ndarray,
            delivered_kept: np.ndarray) -> ParticleAccount:
    """Count a shift's particles now.

    Args:
        positions_m: (n, 3) particle centres in the world frame, m.
        radius_m: particle radius, m.
        in_bucket: (n,) inside the bucket's volume.
        delivered: (n,) counted as delivered so far.
        delivered_kept: (n,) lying where delivered particles are kept.

    Returns:
        The particles by group; a delivered particle not kept where delivered ones are, or a particle that is
        not finite, below the ground or outside the world, is unaccounted for.
    """
    positions_m = np.asarray(positions_m, dtype=float)
    in_world = (np.all(np.isfinite(positions_m), axis=1) & (positions_m[:, 2] > -radius_m)
                & np.all(np.abs(positions_m[:, :2]) < WORLD_HALF_SIZE_M, axis=1))
    delivered_ok = delivered & delivered_kept & in_world
    bucket = in_bucket & in_world & ~delivered
    pile = touching_cluster(positions_m, radius_m, in_world & ~delivered & ~bucket)
    spilled = in_world & ~delivered & ~bucket & ~pile
    unaccounted = ~(delivered_ok | bucket | pile | spilled)
    return ParticleAccount(pile=pile, bucket=bucket, delivered=delivered_ok, spilled=spilled, unaccounted=unaccounted)


def pile_profile(positions_m: np.ndarray, radius_m: float, pile: np.ndarray, bin_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The pile's surface along x: at points ``bin_m`` apart, the top of the highest particle over each point.

    Returns:
        (points in world x, m; heights above the ground, m; 0 where no particle lies over a point), empty
        without a pile.
    """
    if not pile.any():
        return np.zeros(0), np.zeros(0)
    xs, zs = positions_m[pile, 0], positions_m[pile, 2]
    points = np.arange(xs.min() - radius_m, xs.max() + radius_m + bin_m / 2, bin_m)
    offsets = points[:, None] - xs[None, :]
    over = np.abs(offsets) <= radius_m
    tops = np.where(over, zs[None, :] + np.sqrt(np.clip(radius_m ** 2 - offsets ** 2, 0.0, None)), 0.0)
    return points, tops.max(axis=1)
