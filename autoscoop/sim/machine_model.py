"""A machine's MJCF against its machine.yaml: it compiles, and its named parts have the YAML's numbers.

Parts are found by name, as every module reads the model: bodies ``chassis``, ``arm_base``, ``arm``,
``bucket`` and ``wheel_fl`` / ``wheel_fr`` / ``wheel_rl`` / ``wheel_rr``; joints and actuators ``lift``,
``tilt`` and the four wheels; site ``tip``; the bucket's side plates, geoms ``bucket_side_left`` and
``bucket_side_right``; and every sensor the YAML lists. Lengths in m, masses in kg.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from autoscoop.core.machine import Machine

WHEELS = ("wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr")
SIDE_PLATES = ("bucket_side_left", "bucket_side_right")
LENGTH_TOLERANCE = 1e-3
"""Largest disagreement of a length, as a share of the chassis length (0.5 mm on the Komodo): the MJCF
writes some points rounded (an arm's centre of mass given along its line in the YAML)."""
VALUE_TOLERANCE = 1e-6
"""Largest relative disagreement of a mass, a range, a limit or a speed."""


def load_model(machine: Machine) -> mujoco.MjModel:
    """The machine's compiled MJCF.

    Raises:
        ValueError: it does not compile; the message names the file and MuJoCo's reason.
    """
    path = machine.mjcf_path()
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as error:
        raise ValueError(f"mjcf = {machine.mjcf!r}: {path} does not compile: {error}") from None


def disagreements(machine: Machine, model: mujoco.MjModel) -> list[str]:
    """Where the MJCF and the YAML disagree, one line each naming the YAML field and the MJCF part."""
    out: list[str] = []
    scale = machine.chassis.size_m[0]

    def part(kind: str, name: str, field: str):
        try:
            return getattr(model, kind)(name)
        except KeyError:
            out.append(f"{field}: the MJCF has no {kind} named {name!r}")
            return None

    def same(field: str, yaml_value: float | Sequence[float], mjcf_value: np.ndarray | float, what: str,
             length: bool = False) -> None:
        a, b = np.atleast_1d(np.asarray(yaml_value, dtype=float)), np.atleast_1d(np.asarray(mjcf_value, dtype=float))
        tolerance = LENGTH_TOLERANCE * scale if length else VALUE_TOLERANCE * max(1.0, float(np.abs(a).max()))
        if a.shape != b.shape or not np.allclose(a, b, rtol=0.0, atol=tolerance):
            out.append(f"{field} = {_fmt(a)} but the MJCF's {what} is {_fmt(b)}")

    def xz(vector: np.ndarray) -> np.ndarray:
        return np.asarray(vector)[[0, 2]]

    body = part("body", "chassis", "chassis")
    if body is not None:
        same("chassis.centre_height_m", machine.chassis.centre_height_m, body.pos[2], "body 'chassis' pos z", True)
        same("chassis.mass_kg", machine.chassis.mass_kg, body.mass[0], "body 'chassis' mass")
        same("chassis.com_m", machine.chassis.com_m, xz(body.ipos), "body 'chassis' centre of mass (x, z)", True)
    geom = part("geom", "chassis", "chassis.size_m")
    if geom is not None:
        same("chassis.size_m", machine.chassis.size_m, 2 * geom.size, "geom 'chassis' full size", True)
    body = part("body", "arm_base", "arm")
    if body is not None:
        same("arm.base_from_chassis_m", machine.arm.base_from_chassis_m, xz(body.pos), "body 'arm_base' pos (x, z)", True)
        same("arm.base_mass_kg", machine.arm.base_mass_kg, body.mass[0], "body 'arm_base' mass")
        same("arm.base_com_m", machine.arm.base_com_m, xz(body.ipos), "body 'arm_base' centre of mass (x, z)", True)
    body = part("body", "arm", "arm")
    if body is not None:
        same("arm.lift_joint_from_base_m", machine.arm.lift_joint_from_base_m, xz(body.pos), "body 'arm' pos (x, z)", True)
        same("arm.mass_kg", machine.arm.mass_kg, body.mass[0], "body 'arm' mass")
        line = np.asarray(machine.arm.tilt_joint_from_lift_joint_m)
        same("arm.com_along_m", machine.arm.com_along_m, float(xz(body.ipos) @ line / np.linalg.norm(line)),
             "body 'arm' centre of mass along the arm", True)
    body = part("body", "bucket", "bucket")
    if body is not None:
        same("arm.tilt_joint_from_lift_joint_m", machine.arm.tilt_joint_from_lift_joint_m, xz(body.pos),
             "body 'bucket' pos (x, z)", True)
        same("bucket.mass_kg", machine.bucket.mass_kg, body.mass[0], "body 'bucket' mass")
        same("bucket.com_from_tilt_joint_m", machine.bucket.com_from_tilt_joint_m, body.ipos[0],
             "body 'bucket' centre of mass x", True)
        w, x, y, z = body.quat
        if abs(x) > 1e-6 or abs(z) > 1e-6:
            out.append("bucket.mount_pitch_rad: the MJCF's body 'bucket' is turned about an axis other than y")
        same("bucket.mount_pitch_rad", machine.bucket.mount_pitch_rad, 2.0 * math.atan2(y, w),
             "body 'bucket' pitch")
        for name in SIDE_PLATES:
            if part("geom", name, "bucket.inner_half_width_m") is not None:
                same("bucket.inner_half_width_m", machine.bucket.inner_half_width_m,
                     inner_face_from_bucket_centre(model, name), f"geom {name!r} inner face from the bucket's centre "
                     "(y)", True)
    site = part("site", "tip", "bucket.tip_from_tilt_joint_m")
    if site is not None:
        same("bucket.tip_from_tilt_joint_m", [machine.bucket.tip_from_tilt_joint_m, 0.0], xz(site.pos),
             "site 'tip' pos (x, z)", True)

    for name in ("lift", "tilt"):
        spec = getattr(machine.joints, name)
        joint = part("joint", name, f"joints.{name}")
        if joint is not None:
            if int(joint.type[0]) != int(mujoco.mjtJoint.mjJNT_HINGE) or not np.allclose(joint.axis, [0, 1, 0]):
                out.append(f"joints.{name}: the MJCF's joint {name!r} must be a hinge about +y")
            same(f"joints.{name}.range_rad", spec.range_rad, joint.range, f"joint {name!r} range")
            dof = int(joint.dofadr[0])
            same(f"joints.{name}.damping_nms", spec.damping_nms, model.dof_damping[dof], f"joint {name!r} damping")
            same(f"joints.{name}.armature_kgm2", spec.armature_kgm2, model.dof_armature[dof], f"joint {name!r} armature")
        actuator = part("actuator", name, f"actuators.{name}")
        if actuator is not None:
            limits = getattr(machine.actuators, name)
            same(f"actuators.{name}.torque_limit_nm", [-limits.torque_limit_nm, limits.torque_limit_nm],
                 actuator.forcerange, f"actuator {name!r} forcerange")
            same(f"actuators.{name}.max_speed_radps", [-limits.max_speed_radps, limits.max_speed_radps],
                 actuator.ctrlrange, f"actuator {name!r} ctrlrange")
            if int(model.actuator_actnum[actuator.id]):
                same(f"joints.{name}.range_rad", spec.range_rad, model.actuator_actrange[actuator.id],
                     f"actuator {name!r} actrange")

    wheels = machine.wheels
    for name in WHEELS:
        body = part("body", name, "wheels")
        if body is not None:
            axle = wheels.axle_x_m[1] if name[-2] == "f" else wheels.axle_x_m[0]
            same("wheels.axle_x_m", axle, body.pos[0], f"body {name!r} pos x", True)
            same("wheels.track_m", wheels.track_m, 2 * abs(body.pos[1]), f"body {name!r} distance across", True)
            same("wheels.mass_kg", wheels.mass_kg, body.mass[0], f"body {name!r} mass")
        geom = part("geom", name, "wheels")
        if geom is not None:
            same("wheels.radius_m", wheels.radius_m, geom.size[0], f"geom {name!r} radius", True)
            same("wheels.width_m", wheels.width_m, 2 * geom.size[1], f"geom {name!r} width", True)
        actuator = part("actuator", name, "actuators.drive")
        if actuator is not None:
            limit = machine.actuators.drive.wheel_torque_limit_nm
            same("actuators.drive.wheel_torque_limit_nm", [-limit, limit], actuator.forcerange,
                 f"actuator {name!r} forcerange")

    for i, sensor in enumerate(machine.sensors):
        part("sensor", sensor.name, f"sensors[{i}].name")
    return out


def inner_face_from_bucket_centre(model: mujoco.MjModel, geom_name: str) -> float:
    """How far the face of a bucket's side plate nearest the bucket's centre line lies from it (m, along the
    bucket frame's y): the nearest of the plate's vertices (a mesh's, or a box's corners) at the model's rest pose."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    geom = model.geom(geom_name)
    if int(geom.type[0]) == int(mujoco.mjtGeom.mjGEOM_MESH):
        mesh = int(geom.dataid[0])
        start, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        local = np.asarray(model.mesh_vert[start:start + count], dtype=float)
    else:
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
        local = signs * np.asarray(geom.size, dtype=float)
    world = data.geom_xpos[geom.id] + local @ data.geom_xmat[geom.id].reshape(3, 3).T
    bucket = model.body("bucket").id
    in_bucket = (world - data.xpos[bucket]) @ data.xmat[bucket].reshape(3, 3)
    return float(np.abs(in_bucket[:, 1]).min())


def _fmt(values: np.ndarray) -> str:
    text = ", ".join(f"{v:.6g}" for v in values)
    return text if values.size == 1 else f"[{text}]"
