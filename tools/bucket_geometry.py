"""Print the bucket's collision plates for ``autoscoop/machines/komodo/loader.xml``.

The bucket's inner outline is the paper's quadrilateral (docs/definitions.md): tilt joint J, point A 0.124 m
from J at +46 deg, cutting edge (tip) 0.215 m from J at 0 deg, point B 0.10 m from J at -41 deg,
angles measured from the J->tip line. Frame: the bucket body frame, x along J->tip, z toward A,
y across the bucket. The outline and the inner width are read from ``autoscoop.core.kinematics`` (the
same numbers that count particles as inside), so the defaults print the plates in ``loader.xml``
(a test checks that). The shell is B->J->A (back) and B->tip (floor); A->tip is the mouth. Each
plate lies outside the outline with its inner face on it, so a particle's centre inside the
outline is inside the bucket. The back plates are boxes; the floor is a convex wedge that tapers
to a sharp cutting edge (a blunt 2 cm edge pushes the pile instead of slicing under it). Run: ``python tools/bucket_geometry.py``.
"""

import argparse
import math

import numpy as np

from autoscoop.core.kinematics import BUCKET_INNER_HALF_WIDTH_M, BUCKET_INSIDE_POLYGON_M

J, A, TIP, B = BUCKET_INSIDE_POLYGON_M
PLATE_THICKNESS_M = 0.02
"""Thickness of the bucket's plates (2 cm, so a falling particle cannot tunnel through at 1/48 s), m."""
CENTROID = (J + A + TIP + B) / 4


def plate(p: np.ndarray, q: np.ndarray, thickness: float, half_width: float, name: str) -> str:
    """One box along segment p->q (lengthened by the thickness to close the corners), pushed outward."""
    d = (q - p) / np.linalg.norm(q - p)
    n = np.array([d[1], -d[0]])
    if np.dot(n, (p + q) / 2 - CENTROID) < 0:
        n = -n
    centre = (p + q) / 2 + n * thickness / 2
    half_length = np.linalg.norm(q - p) / 2 + thickness / 2
    # a rotation about +y by angle a maps x to (cos a, 0, -sin a)
    pitch = -math.atan2(d[1], d[0])
    return (f'<geom name="{name}" class="bucket_plate" size="{half_length:.5f} {half_width:.4f} {thickness / 2:.4f}" '
            f'pos="{centre[0]:.5f} 0 {centre[1]:.5f}" euler="0 {pitch:.5f} 0"/>')


def floor_wedge(thickness: float, half_width: float, edge_thickness: float = 0.002) -> str:
    """The floor as a convex wedge: ``thickness`` under B, tapering to a sharp cutting edge at the tip."""
    d = (TIP - B) / np.linalg.norm(TIP - B)
    n = np.array([d[1], -d[0]])
    if np.dot(n, (B + TIP) / 2 - CENTROID) < 0:
        n = -n
    section = [B, TIP, TIP + n * edge_thickness, B + n * thickness]
    verts = " ".join(f"{x:.5f} {y:.4f} {z:.5f}" for x, z in section for y in (-half_width, half_width))
    return f'<mesh name="bucket_floor" vertex="{verts}"/>'


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--width", type=float, default=2 * BUCKET_INNER_HALF_WIDTH_M,
                        help="inner width across the bucket, m (default: autoscoop.core.kinematics)")
    parser.add_argument("--thickness", type=float, default=PLATE_THICKNESS_M, help="plate thickness, m")
    args = parser.parse_args()
    hw, t = args.width / 2, args.thickness
    print(floor_wedge(t, hw + t))
    print(plate(J, B, t, hw + t, "bucket_back_lower"))
    print(plate(A, J, t, hw + t, "bucket_back_upper"))
    verts = " ".join(f"{x:.5f} {y:.4f} {z:.5f}" for x, z in (J, A, TIP, B) for y in (-t / 2, t / 2))
    print(f'<mesh name="bucket_side" vertex="{verts}"/>')
    print(f'side plates at y = +-{hw + t / 2:.4f}')
    xs, zs = np.array([J, A, TIP, B]).T
    area = 0.5 * abs(np.dot(xs, np.roll(zs, -1)) - np.dot(zs, np.roll(xs, -1)))
    print(f"inner cross-section {area:.5f} m^2, volume {area * args.width * 1000:.2f} L")


if __name__ == "__main__":
    main()
