"""Planar forward kinematics of the loader's arm, numpy only.

Frame ("chassis frame"): x forward from the chassis centre, z up from the ground under it, metres;
the arm moves in this x-z plane. Angles in radians. Both arm joints turn about the chassis +y axis
(y to the robot's left), so a positive angle pitches the part forward-down: a larger lift angle
lowers the arm, a larger tilt angle tips the cutting edge down. The module's names are the machine this process
runs (:func:`autoscoop.core.machine.selected_machine`: ``--machine`` or ``$AUTOSCOOP_MACHINE``, else ``komodo``,
``autoscoop/machines/komodo/machine.yaml``); its MJCF is built from the same numbers and
``autoscoop machine check`` and a test check that they agree.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autoscoop.core.machine import load_machine, selected_machine

MACHINE = load_machine(selected_machine())
"""The machine these names describe (its ``machine.yaml`` is the source of every number), chosen once per process."""

CHASSIS_CENTRE_HEIGHT_M = MACHINE.chassis.centre_height_m
ARM_BASE_FROM_CHASSIS_M = MACHINE.arm.base_from_chassis_m
LIFT_JOINT_FROM_ARM_BASE_M = MACHINE.arm.lift_joint_from_base_m
TILT_JOINT_FROM_LIFT_JOINT_M = MACHINE.arm.tilt_joint_from_lift_joint_m
"""Bucket (tilt) joint relative to the lift joint with the arm at zero, m (x forward, z up)."""
BUCKET_MOUNT_PITCH_RAD = MACHINE.bucket.mount_pitch_rad
"""Pitch-down of the bucket frame (x from tilt joint to cutting edge) at tilt zero, relative to the arm."""
TIP_FROM_TILT_JOINT_M = MACHINE.bucket.tip_from_tilt_joint_m

LIFT_RANGE_RAD = MACHINE.joints.lift.range_rad
TILT_RANGE_RAD = MACHINE.joints.tilt.range_rad

ARM_MASS_KG = MACHINE.arm.mass_kg
ARM_COM_ALONG_M = MACHINE.arm.com_along_m
BUCKET_MASS_KG = MACHINE.bucket.mass_kg
BUCKET_COM_FROM_TILT_JOINT_M = MACHINE.bucket.com_from_tilt_joint_m

LIFT_JOINT_M = np.array([
    ARM_BASE_FROM_CHASSIS_M[0] + LIFT_JOINT_FROM_ARM_BASE_M[0],
    CHASSIS_CENTRE_HEIGHT_M + ARM_BASE_FROM_CHASSIS_M[1] + LIFT_JOINT_FROM_ARM_BASE_M[1],
])
"""Lift joint in the chassis frame, m."""


def pitch(vector_xz: np.ndarray, angle_rad: float | np.ndarray) -> np.ndarray:
    """Rotate x-z vectors about +y by ``angle_rad`` (positive turns +x toward -z).

    Args:
        vector_xz: (..., 2) array of (x, z).
        angle_rad: rotation angle(s), broadcast against the leading axes.

    Returns:
        The rotated (..., 2) array.
    """
    v = np.asarray(vector_xz, dtype=float)
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.stack([v[..., 0] * c + v[..., 1] * s, -v[..., 0] * s + v[..., 1] * c], axis=-1)


@dataclass(frozen=True)
class ArmPose:
    """Points of the arm in the chassis frame, (x, z) in metres."""

    lift_joint: np.ndarray
    bucket_joint: np.ndarray
    tip: np.ndarray


def bucket_joint_position(lift_rad: float | np.ndarray) -> np.ndarray:
    """Tilt (bucket) joint in the chassis frame, (..., 2) metres."""
    return LIFT_JOINT_M + pitch(np.array(TILT_JOINT_FROM_LIFT_JOINT_M), np.asarray(lift_rad, dtype=float))


def bucket_angle(lift_rad: float | np.ndarray, tilt_rad: float | np.ndarray) -> np.ndarray:
    """Pitch-down of the tilt-joint -> cutting-edge line from horizontal, radians."""
    return np.asarray(lift_rad) + BUCKET_MOUNT_PITCH_RAD + np.asarray(tilt_rad)


def bucket_point(lift_rad: float | np.ndarray, tilt_rad: float | np.ndarray,
                 point_in_bucket_m: np.ndarray) -> np.ndarray:
    """A point given in the bucket frame (x to the cutting edge, z toward the mouth), in the chassis frame.

    Args:
        lift_rad: lift angle(s).
        tilt_rad: tilt angle(s).
        point_in_bucket_m: (2,) point (x, z) in the bucket frame, metres.

    Returns:
        (..., 2) point in the chassis frame, metres.
    """
    return bucket_joint_position(lift_rad) + pitch(np.asarray(point_in_bucket_m, dtype=float),
                                                   bucket_angle(lift_rad, tilt_rad))


def arm_pose(lift_rad: float | np.ndarray, tilt_rad: float | np.ndarray) -> ArmPose:
    """Lift joint, bucket joint and cutting edge (tip) in the chassis frame."""
    lift = np.asarray(lift_rad, dtype=float)
    return ArmPose(
        lift_joint=np.broadcast_to(LIFT_JOINT_M, lift.shape + (2,)).copy(),
        bucket_joint=bucket_joint_position(lift),
        tip=bucket_point(lift, tilt_rad, np.array([TIP_FROM_TILT_JOINT_M, 0.0])),
    )


BUCKET_INSIDE_POLYGON_M = np.array(MACHINE.bucket.inside_polygon_m, dtype=float)
"""The in-bucket outline in the bucket frame (x to the cutting edge, z toward the mouth), m, clockwise and
convex; for the Komodo the paper's quadrilateral: tilt joint, 0.124 m at +46 deg, cutting edge, 0.10 m at -41 deg."""
_EDGES = np.roll(BUCKET_INSIDE_POLYGON_M, -1, axis=0) - BUCKET_INSIDE_POLYGON_M
_EDGE_OFFSETS = BUCKET_INSIDE_POLYGON_M[:, 1] * _EDGES[:, 0] - BUCKET_INSIDE_POLYGON_M[:, 0] * _EDGES[:, 1]
BUCKET_INNER_HALF_WIDTH_M = MACHINE.bucket.inner_half_width_m
"""Half the bucket's inner width across (y), m."""


def inside_bucket(points_in_bucket_frame: np.ndarray) -> np.ndarray:
    """Which points lie inside the bucket's volume.

    Args:
        points_in_bucket_frame: (n, 3) points in the bucket frame (x to the cutting edge, y across,
            z toward the mouth), metres.

    Returns:
        (n,) boolean mask: inside the quadrilateral in x-z and within the inner width in y.
    """
    p = np.asarray(points_in_bucket_frame, dtype=float)
    # a point is inside the clockwise polygon when it lies right of (or on) every edge:
    # edge x (p - vertex) <= 0, i.e. p_z * e_x - p_x * e_z <= v_z * e_x - v_x * e_z for every edge
    cross = np.outer(p[:, 2], _EDGES[:, 0]) - np.outer(p[:, 0], _EDGES[:, 1])
    return (cross <= _EDGE_OFFSETS).all(axis=1) & (np.abs(p[:, 1]) <= BUCKET_INNER_HALF_WIDTH_M)

