"""What a machine can do, from its numbers alone (numpy only): bucket capacity, reach, static tipping.

Frames as in :mod:`autoscoop.core.machine`: chassis frame x forward from the chassis centre, z up from the
ground, metres; bucket frame origin the tilt joint, x to the cutting edge, z toward the mouth. The machine
stands on level ground; angles in radians, positive pitching forward-down.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autoscoop.core.config import RobotConfig
from autoscoop.core.kinematics import pitch
from autoscoop.core.machine import Machine, polygon_signed_area

RATED_SHARE_OF_TIPPING_LOAD = 0.5
"""Largest rated load as a share of the static tipping load: SAE J818 and ISO 14397-1 rate a skid-steer
loader's operating capacity at 50 % of its tipping load."""
POSE_GRID = 121
"""Samples of each joint's range when searching poses (121: a step of 0.35 % of the range)."""
CUTTING_EDGE_TOLERANCE_M = 1e-3
"""A point of the bucket outline within this of the cutting edge is the cutting edge."""


@dataclass(frozen=True)
class Capacity:
    """The bucket's volume, SAE J742 / ISO 7546 style, m^3."""

    struck_m3: float
    """the outline's area times the inner width: full to the strike plane (cutting edge to the top of the back)."""
    heaped_m3: float
    """struck plus a heap at 1:2 slope above the strike plane: W L^2 / 8 - L^3 / 24, with L the strike plane's
    length from the cutting edge to the top of the back and W the inner width."""
    strike_length_m: float


@dataclass(frozen=True)
class Reach:
    """The highest the cutting edge can go over the joints' ranges."""

    tip_height_m: float
    """highest cutting edge above the ground, m."""
    tip_x_m: float
    """the cutting edge's x there, chassis frame, m."""
    lift_rad: float
    tilt_rad: float


@dataclass(frozen=True)
class Tipping:
    """Static tipping forward over the front axle with a load at the bucket's load centre, at full reach."""

    tipping_load_kg: float
    """the load at the load centre that lifts the rear wheels, kg (inf when it never tips)."""
    rated_share: float
    """rated load / tipping load."""
    load_centre_x_m: float
    """the load centre's x at full reach, chassis frame, m."""
    lift_rad: float
    """the lift angle of full reach (tilt at its curled-back limit, as a load is carried)."""
    robot_mass_kg: float


def joints_in_chassis(machine: Machine) -> np.ndarray:
    """The lift joint (x, z) in the chassis frame (z from the ground), m."""
    arm = machine.arm
    return np.array([arm.base_from_chassis_m[0] + arm.lift_joint_from_base_m[0],
                     machine.chassis.centre_height_m + arm.base_from_chassis_m[1] + arm.lift_joint_from_base_m[1]])


def bucket_point(machine: Machine, lift_rad: np.ndarray | float, tilt_rad: np.ndarray | float,
                 point_in_bucket_m: np.ndarray) -> np.ndarray:
    """A bucket-frame point in the chassis frame, (..., 2) m."""
    lift = np.asarray(lift_rad, dtype=float)
    joint = joints_in_chassis(machine) + pitch(np.array(machine.arm.tilt_joint_from_lift_joint_m), lift)
    angle = lift + machine.bucket.mount_pitch_rad + np.asarray(tilt_rad, dtype=float)
    return joint + pitch(np.asarray(point_in_bucket_m, dtype=float), angle)


def cutting_edge_index(machine: Machine) -> int | None:
    """Index of the outline's point at the cutting edge (``bucket.tip_from_tilt_joint_m``, 0), None when none is."""
    tip = np.array([machine.bucket.tip_from_tilt_joint_m, 0.0])
    distances = np.linalg.norm(np.asarray(machine.bucket.inside_polygon_m) - tip, axis=1)
    i = int(np.argmin(distances))
    return i if distances[i] <= CUTTING_EDGE_TOLERANCE_M else None


def capacity(machine: Machine) -> Capacity:
    """Struck and heaped capacity. The strike plane is the outline's edge that arrives at the cutting edge
    (clockwise, the mouth); without a point at the cutting edge the heap is left out (struck only)."""
    outline = np.asarray(machine.bucket.inside_polygon_m, dtype=float)
    width = 2.0 * machine.bucket.inner_half_width_m
    struck = abs(polygon_signed_area([tuple(p) for p in outline])) * width
    i = cutting_edge_index(machine)
    if i is None:
        return Capacity(struck, struck, 0.0)
    length = float(np.linalg.norm(outline[i] - outline[i - 1]))
    heap = max(0.0, width * length**2 / 8.0 - length**3 / 24.0)
    return Capacity(struck, struck + heap, length)


def _grid(lo_hi: tuple[float, float]) -> np.ndarray:
    return np.linspace(lo_hi[0], lo_hi[1], POSE_GRID)


def reach(machine: Machine) -> Reach:
    """The highest cutting edge over the joints' ranges (a grid of poses)."""
    lift, tilt = np.meshgrid(_grid(machine.joints.lift.range_rad), _grid(machine.joints.tilt.range_rad))
    tip = bucket_point(machine, lift, tilt, np.array([machine.bucket.tip_from_tilt_joint_m, 0.0]))
    i = np.unravel_index(int(np.argmax(tip[..., 1])), lift.shape)
    return Reach(float(tip[..., 1][i]), float(tip[..., 0][i]), float(lift[i]), float(tilt[i]))


@dataclass(frozen=True)
class StartPose:
    """The bucket at the start of an episode: the scene's ``robot.start_lift_rad`` and ``robot.start_tilt_rad``."""

    lift_rad: float
    tilt_rad: float
    tip_height_m: float
    """the cutting edge above the ground, m (negative: under it)."""
    lowest_height_m: float
    """the bucket outline's lowest point above the ground, m."""


def start_pose(machine: Machine) -> StartPose:
    """Where the bucket starts: the machine's ``scene`` start angles, else the config schema's defaults."""
    fields = RobotConfig.model_fields
    lift = float(machine.scene.get("robot.start_lift_rad", fields["start_lift_rad"].default))
    tilt = float(machine.scene.get("robot.start_tilt_rad", fields["start_tilt_rad"].default))
    tip = bucket_point(machine, lift, tilt, np.array([machine.bucket.tip_from_tilt_joint_m, 0.0]))
    outline = bucket_point(machine, lift, tilt, np.asarray(machine.bucket.inside_polygon_m, dtype=float))
    return StartPose(lift, tilt, float(tip[1]), float(outline[:, 1].min()))


def robot_mass_kg(machine: Machine) -> float:
    """Chassis, four wheels, arm base, arm and bucket, kg."""
    return (machine.chassis.mass_kg + 4 * machine.wheels.mass_kg + machine.arm.base_mass_kg
            + machine.arm.mass_kg + machine.bucket.mass_kg)


def tipping(machine: Machine) -> Tipping:
    """Static tipping over the front axle at full reach with the rated load at the load centre.

    Full reach: the lift angle, over its range, that puts the load centre (the outline's centroid) farthest
    forward with the bucket curled back to its tilt limit. The tipping load balances the moments of every
    part about the front wheels' ground contact: load * (x_load - x_front) = sum of m * (x_front - x).
    """
    arm, bucket = machine.arm, machine.bucket
    outline = np.asarray(bucket.inside_polygon_m, dtype=float)
    centroid = _centroid(outline)
    lift = _grid(machine.joints.lift.range_rad)
    tilt = machine.joints.tilt.range_rad[0]
    load_x = bucket_point(machine, lift, tilt, centroid)[..., 0]
    k = int(np.argmax(load_x))
    front, rear = machine.wheels.axle_x_m[1], machine.wheels.axle_x_m[0]
    length = np.hypot(*arm.tilt_joint_from_lift_joint_m)
    arm_com = joints_in_chassis(machine) + pitch(np.array(arm.tilt_joint_from_lift_joint_m) * arm.com_along_m / length,
                                                 lift[k])
    bucket_com = bucket_point(machine, lift[k], tilt, np.array([bucket.com_from_tilt_joint_m, 0.0]))
    parts = [(machine.chassis.mass_kg, machine.chassis.com_m[0]),
             (2 * machine.wheels.mass_kg, rear), (2 * machine.wheels.mass_kg, front),
             (arm.base_mass_kg, arm.base_from_chassis_m[0] + arm.base_com_m[0]),
             (arm.mass_kg, float(arm_com[0])), (bucket.mass_kg, float(bucket_com[0]))]
    restoring = sum(m * (front - x) for m, x in parts)
    lever = float(load_x[k]) - front
    tipping_load = restoring / lever if lever > 0 else float("inf")
    share = bucket.rated_load_kg / tipping_load if tipping_load > 0 else float("inf")
    return Tipping(tipping_load, share, float(load_x[k]), float(lift[k]), robot_mass_kg(machine))


def _centroid(outline: np.ndarray) -> np.ndarray:
    x, z = outline[:, 0], outline[:, 1]
    xn, zn = np.roll(x, -1), np.roll(z, -1)
    cross = x * zn - xn * z
    area = cross.sum() / 2.0
    return np.array([((x + xn) * cross).sum(), ((z + zn) * cross).sum()]) / (6.0 * area)


def problems(machine: Machine) -> list[str]:
    """What keeps the machine from working, each naming the field: the cutting edge on the outline, the
    terminal point reachable ahead of the chassis, the rated load within the tipping rule."""
    out = []
    if cutting_edge_index(machine) is None:
        out.append(f"bucket.inside_polygon_m: no point at the cutting edge ({machine.bucket.tip_from_tilt_joint_m}, 0) "
                   "(bucket.tip_from_tilt_joint_m): the outline must run through it")
    top = reach(machine)
    if top.tip_height_m < machine.task.terminal_height_m:
        out.append(f"task.terminal_height_m = {machine.task.terminal_height_m}: unreachable, the cutting edge rises "
                   f"at most {top.tip_height_m:.3f} m above the ground (lift {top.lift_rad:.3f} rad, tilt "
                   f"{top.tilt_rad:.3f} rad; joints.lift.range_rad, joints.tilt.range_rad, arm.*)")
    elif top.tip_x_m <= machine.chassis.size_m[0] / 2.0:
        out.append(f"task.terminal_height_m = {machine.task.terminal_height_m}: the cutting edge is highest at "
                   f"x = {top.tip_x_m:.3f} m, not ahead of the chassis front ({machine.chassis.size_m[0] / 2:.3f} m)")
    start = start_pose(machine)
    if start.tip_height_m < 0.0 or start.lowest_height_m < 0.0:
        where = "cutting edge" if start.tip_height_m < 0.0 else "bucket floor"
        height = start.tip_height_m if start.tip_height_m < 0.0 else start.lowest_height_m
        out.append(f"scene: robot.start_lift_rad = {start.lift_rad:g}: the bucket starts in the ground (its {where} "
                   f"{-height:.3f} m below it at tilt {start.tilt_rad:g} rad); set the scene's robot.start_lift_rad to "
                   "a lift that holds the level bucket just off the ground (a smaller lift raises it)")
    tip = tipping(machine)
    if tip.tipping_load_kg <= 0.0:
        out.append(f"chassis.com_m = {list(machine.chassis.com_m)}: the machine tips forward over its front axle "
                   "with an empty bucket at full reach: move mass back (chassis.com_m, chassis.mass_kg) or shorten the arm")
    elif machine.bucket.rated_load_basis == "stated" and tip.rated_share >= 1.0:
        out.append(f"bucket.rated_load_kg = {machine.bucket.rated_load_kg}: the machine tips over its front axle "
                   f"with it at full reach (static tipping load {tip.tipping_load_kg:.2f} kg)")
    elif machine.bucket.rated_load_basis == "sae_j818" and tip.rated_share > RATED_SHARE_OF_TIPPING_LOAD:
        out.append(f"bucket.rated_load_kg = {machine.bucket.rated_load_kg}: {100 * tip.rated_share:.0f} % of the "
                   f"static tipping load at full reach ({tip.tipping_load_kg:.2f} kg); at most "
                   f"{100 * RATED_SHARE_OF_TIPPING_LOAD:.0f} % (SAE J818, ISO 14397-1): lower it, or move mass "
                   "back (chassis.com_m, chassis.mass_kg)")
    return out
