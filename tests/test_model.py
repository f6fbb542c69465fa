"""The MJCF compiles, steps with random controls without MuJoCo warnings, and matches the kinematics."""

import math
import warnings

import mujoco
import numpy as np
import pytest

from autoscoop.core import kinematics
from autoscoop.core.config import ScoopConfig
from autoscoop.sim.scene import ScoopSim, scene_path

NAMED = {
    "joint": ["root", "lift", "tilt", "wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"],
    "actuator": ["lift", "tilt", "wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"],
    "site": ["tip", "bucket_joint", "lift_joint", "chassis_centre"],
    "sensor": ["lift_pos", "tilt_pos", "lift_torque", "tilt_torque"],
}


def test_scene_file_compiles_with_named_parts():
    model = mujoco.MjModel.from_xml_path(scene_path())
    for kind, names in NAMED.items():
        for name in names:
            getattr(model, kind)(name)  # raises KeyError when missing
    assert model.jnt_range[model.joint("lift").id].tolist() == pytest.approx(list(kinematics.LIFT_RANGE_RAD))
    assert model.jnt_range[model.joint("tilt").id].tolist() == pytest.approx(list(kinematics.TILT_RANGE_RAD))


def test_random_controls_for_two_seconds_raise_no_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a compile-time MuJoCo warning fails the test
        sim = ScoopSim(ScoopConfig())
    sim.reset(np.random.default_rng(0))
    rng = np.random.default_rng(1)
    steps_per_command = 6
    for _ in range(math.ceil(2.0 / (sim.model.opt.timestep * steps_per_command) - 1e-9)):
        sim.command(rng.uniform(-0.1, 0.1), rng.uniform(-0.4, 0.4), rng.uniform(-1.0, 1.0))
        sim.step(steps_per_command)
    assert sim.elapsed_s >= 2.0 - 1e-9
    assert all(sim.data.warning[i].number == 0 for i in range(len(sim.data.warning)))
    assert sim.is_finite()


def test_forward_kinematics_matches_mujoco_within_a_millimetre():
    sim = ScoopSim(ScoopConfig().with_overrides({"pile.n_particles": 1}))
    m, d = sim.model, sim.data
    rng = np.random.default_rng(2)
    for _ in range(50):
        lift = rng.uniform(*kinematics.LIFT_RANGE_RAD)
        tilt = rng.uniform(*kinematics.TILT_RANGE_RAD)
        mujoco.mj_resetData(m, d)
        sim.set_pose(0.0, lift, tilt)
        mujoco.mj_kinematics(m, d)
        pose = kinematics.arm_pose(lift, tilt)
        chassis = d.xpos[m.body("chassis").id]
        ground = np.array([chassis[0], chassis[2] - kinematics.CHASSIS_CENTRE_HEIGHT_M])
        for site, point in (("tip", pose.tip), ("bucket_joint", pose.bucket_joint), ("lift_joint", pose.lift_joint)):
            xz = d.site(site).xpos[[0, 2]] - ground
            assert np.abs(xz - point).max() < 1e-3, site


def test_bucket_side_plates_bound_the_counted_width():
    model = mujoco.MjModel.from_xml_path(scene_path())
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    bucket = model.body("bucket").id
    inner_faces = []
    for side in ("bucket_side_left", "bucket_side_right"):
        geom = model.geom(side).id
        mesh = model.geom_dataid[geom]
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        world = data.geom_xpos[geom] + model.mesh_vert[start:start + count] @ data.geom_xmat[geom].reshape(3, 3).T
        local_y = (world - data.xpos[bucket]) @ data.xmat[bucket].reshape(3, 3)[:, 1]
        inner_faces.append(np.abs(local_y).min())
    assert inner_faces == pytest.approx([kinematics.BUCKET_INNER_HALF_WIDTH_M] * 2, abs=1e-4)


def test_bucket_plates_in_the_model_are_the_generators_output():
    """tools/bucket_geometry.py with its defaults (the outline of autoscoop.core.kinematics) prints loader.xml's plates."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    printed = subprocess.run([sys.executable, str(root / "tools" / "bucket_geometry.py")], check=True,
                             capture_output=True, text=True).stdout.splitlines()
    plates = [line for line in printed if line.startswith("<")]
    loader = Path(scene_path()).with_name("loader.xml").read_text()
    assert len(plates) == 4
    for line in plates:
        assert line in loader, line


@pytest.mark.parametrize("rolling, dofs", [(False, 3), (True, 6)])
def test_particles_slide_without_turning_unless_rolling(rolling, dofs):
    config = ScoopConfig().with_overrides({"pile.rolling": rolling, "pile.n_particles": 24, "pile.variants": 1})
    sim = ScoopSim(config)
    bodies = np.array([sim.model.body(f"particle_{i:03d}").id for i in range(sim.n_particles)])
    assert (sim.model.body_dofnum[bodies] == dofs).all()
    target = np.array([1.5, 2.0, 0.5])
    sim.set_particle(0, target)
    mujoco.mj_kinematics(sim.model, sim.data)
    assert sim.particle_positions[0] == pytest.approx(target)  # qpos holds the world position either way
    sim.reset(np.random.default_rng(0))
    sim.command(0.1, 0.0, 0.0)
    sim.step(144)  # 3 s: the bucket pushes into the pile
    orientations = sim.data.xquat[bodies]
    turned = np.abs(np.abs(orientations[:, 0]) - 1.0).max()
    assert (turned == 0.0) if not rolling else (turned > 1e-6)
