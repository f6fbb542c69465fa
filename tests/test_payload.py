"""Payload statics (autoscoop.core.payload): kinematics and gravity against MuJoCo, the Jacobian against
finite differences, both estimators on synthetic torques, the calibration fit and its YAML."""

import mujoco
import numpy as np
import pytest

from autoscoop.core import kinematics
from autoscoop.core import payload as P
from autoscoop.sim.scene import scene_path

RNG_SEED = 20211


@pytest.fixture(scope="module")
def loader():
    model = mujoco.MjModel.from_xml_path(scene_path())
    return model, mujoco.MjData(model)


def random_poses(n, seed=RNG_SEED):
    rng = np.random.default_rng(seed)
    return (rng.uniform(*kinematics.LIFT_RANGE_RAD, n), rng.uniform(*kinematics.TILT_RANGE_RAD, n),
            rng.uniform(-0.2, 0.2, n))


def place(model, data, lift, tilt, pitch):
    """The loader somewhere on the ground, pitched by ``pitch`` (nose down), joints at rest; forward."""
    data.qpos[:] = 0.0
    data.qvel[:] = 0.0
    root = model.joint("root").qposadr[0]
    data.qpos[root:root + 7] = [0.4, -0.3, kinematics.CHASSIS_CENTRE_HEIGHT_M, np.cos(pitch / 2), 0, np.sin(pitch / 2), 0]
    data.qpos[model.joint("lift").qposadr[0]] = lift
    data.qpos[model.joint("tilt").qposadr[0]] = tilt
    mujoco.mj_forward(model, data)
    chassis = model.body("chassis").id
    rotation = data.xmat[chassis].reshape(3, 3)
    origin = data.xpos[chassis]

    def in_chassis_frame(world):
        local = rotation.T @ (np.asarray(world) - origin)
        return np.array([local[0], local[2] + kinematics.CHASSIS_CENTRE_HEIGHT_M])

    return in_chassis_frame


def test_kinematics_match_mujoco_positions_within_a_millimetre(loader):
    model, data = loader
    for lift, tilt, pitch in zip(*random_poses(50)):
        local = place(model, data, lift, tilt, pitch)
        pose = kinematics.arm_pose(lift, tilt)
        assert np.linalg.norm(local(data.site("tip").xpos) - pose.tip) <= 1e-3
        assert np.linalg.norm(local(data.site("bucket_joint").xpos) - pose.bucket_joint) <= 1e-3
        assert np.linalg.norm(local(data.site("lift_joint").xpos) - pose.lift_joint) <= 1e-3
        assert np.linalg.norm(local(data.xipos[model.body("arm").id]) - P.arm_com(lift)) <= 1e-3
        assert np.linalg.norm(local(data.xipos[model.body("bucket").id]) - P.bucket_com(lift, tilt)) <= 1e-3


def test_link_masses_match_the_model(loader):
    model, _ = loader
    assert model.body_mass[model.body("arm").id] == pytest.approx(kinematics.ARM_MASS_KG)
    assert model.body_mass[model.body("bucket").id] == pytest.approx(kinematics.BUCKET_MASS_KG)
    assert np.linalg.norm(model.opt.gravity) == pytest.approx(P.GRAVITY_MPS2)


def test_gravity_torques_match_mujoco_bias_at_rest(loader):
    """At zero velocity MuJoCo's bias force on the arm's joints is exactly the torque that holds them: G."""
    model, data = loader
    dofs = [model.joint("lift").dofadr[0], model.joint("tilt").dofadr[0]]
    for lift, tilt, pitch in zip(*random_poses(30)):
        place(model, data, lift, tilt, pitch)
        np.testing.assert_allclose(P.gravity_torques(lift, tilt, pitch), data.qfrc_bias[dofs], atol=0.01)


def test_bucket_jacobian_matches_finite_differences_and_mujoco(loader):
    model, data = loader
    h = 1e-6
    point = np.array([0.12, 0.03])
    bucket = model.body("bucket").id
    dofs = [model.joint("lift").dofadr[0], model.joint("tilt").dofadr[0]]
    for lift, tilt, _ in zip(*random_poses(20)):
        jac = P.bucket_point_jacobian(lift, tilt, point)
        d_lift = (kinematics.bucket_point(lift + h, tilt, point) - kinematics.bucket_point(lift - h, tilt, point)) / (2 * h)
        d_tilt = (kinematics.bucket_point(lift, tilt + h, point) - kinematics.bucket_point(lift, tilt - h, point)) / (2 * h)
        np.testing.assert_allclose(jac, np.stack([d_lift, d_tilt], axis=-1), atol=1e-8)
        # MuJoCo's own Jacobian of the same point (chassis level, so chassis x-z = world x-z)
        place(model, data, lift, tilt, 0.0)
        world = data.xpos[bucket] + data.xmat[bucket].reshape(3, 3) @ np.array([point[0], 0.0, point[1]])
        jacp = np.zeros((3, model.nv))
        mujoco.mj_jac(model, data, jacp, None, world, bucket)
        np.testing.assert_allclose(jac, jacp[[0, 2]][:, dofs], atol=1e-9)
    arm = P.arm_point_jacobian(0.1, P.ARM_COM_IN_ARM_M)
    d = (P.arm_com(0.1 + h) - P.arm_com(0.1 - h)) / (2 * h)
    np.testing.assert_allclose(arm[:, 0], d, atol=1e-8)
    assert np.all(arm[:, 1] == 0)


def random_points_in_bucket(n, rng):
    """Points inside the in-bucket quadrilateral (bucket frame, x-z)."""
    out = []
    while len(out) < n:
        p = rng.uniform([0.0, -0.07], [0.215, 0.09])
        if kinematics.inside_bucket(np.array([[p[0], 0.0, p[1]]]))[0]:
            out.append(p)
    return np.array(out)


def synthetic_torques(lift, tilt, pitch, mass, point, offsets=(0.0, 0.0)):
    """tau = G + J^T (m g up) + offset: the payload's weight held at ``point`` (bucket frame)."""
    up = P.up_in_chassis(pitch)
    jac = P.bucket_point_jacobian(lift, tilt, point)
    return P.gravity_torques(lift, tilt, pitch) + jac.T @ (mass * P.GRAVITY_MPS2 * up) + np.asarray(offsets)


def test_estimators_recover_the_mass_exactly_without_noise():
    rng = np.random.default_rng(1)
    lifts, tilts, pitches = random_poses(40, seed=2)
    points = random_points_in_bucket(40, rng)
    for lift, tilt, pitch, point in zip(lifts, tilts, pitches, points):
        mass = rng.uniform(0.0, 9.0)
        offsets = rng.uniform(-1, 1, 2)
        tau = synthetic_torques(lift, tilt, pitch, mass, point, offsets)
        calibration = P.PayloadCalibration(lift_offset_nm=offsets[0], tilt_offset_nm=offsets[1],
                                           payload_com_in_bucket_m=tuple(point))
        assert P.mass_eq8(lift, tilt, tau[0], tau[1], calibration, pitch) == pytest.approx(mass, abs=1e-9)
        assert P.mass_eq4(lift, tilt, tau[1], calibration, pitch) == pytest.approx(mass, abs=1e-9)
        if mass > 0.5:
            lever = P.payload_line_of_action(lift, tilt, tau[0], tau[1], calibration, pitch)
            assert lever == pytest.approx(P.payload_lever_arm(lift, tilt, calibration, pitch), abs=1e-9)
        force = P.payload_force(lift, tilt, tau - offsets, point, pitch)
        np.testing.assert_allclose(force, mass * P.GRAVITY_MPS2 * P.up_in_chassis(pitch), atol=1e-8)


def test_the_reported_mass_keeps_the_last_report_when_undefined_and_reads_zero_below_the_floor():
    assert P.reported_mass_kg(3.2, 1.0) == 3.2
    assert P.reported_mass_kg(-0.1, 1.0) == 0.0  # noise on an empty bucket
    assert P.reported_mass_kg(0.2, 1.0, empty_below_kg=0.3) == 0.0
    assert P.reported_mass_kg(-0.1, 1.0, empty_below_kg=-np.inf) == -0.1
    for undefined in (np.nan, np.inf, -np.inf):
        assert P.reported_mass_kg(undefined, 1.7) == 1.7


def test_eq8_needs_no_lever_arm_but_eq4_does():
    lift, tilt, mass = -0.05, -0.4, 5.0
    tau = synthetic_torques(lift, tilt, 0.0, mass, np.array([0.15, 0.05]))
    wrong = P.PayloadCalibration(payload_com_in_bucket_m=(0.08, 0.0))
    assert P.mass_eq8(lift, tilt, tau[0], tau[1], wrong) == pytest.approx(mass, abs=1e-9)
    assert abs(P.mass_eq4(lift, tilt, tau[1], wrong) - mass) > 1.0


def test_estimators_are_vectorised():
    lifts, tilts, pitches = random_poses(7, seed=3)
    tau = np.array([synthetic_torques(a, b, c, 2.0, np.array([0.1, 0.0])) for a, b, c in zip(lifts, tilts, pitches)])
    masses = P.mass_eq8(lifts, tilts, tau[:, 0], tau[:, 1], chassis_pitch_rad=pitches)
    assert masses.shape == (7,)
    np.testing.assert_allclose(masses, 2.0, atol=1e-9)


def test_calibration_recovers_a_known_lever_arm_and_offsets():
    rng = np.random.default_rng(4)
    truth = P.PayloadCalibration(lift_offset_nm=0.7, tilt_offset_nm=-0.3, payload_com_in_bucket_m=(0.125, 0.04))
    lifts, tilts, _ = random_poses(60, seed=5)
    masses = rng.uniform(0.0, 7.5, 60)
    tau = np.array([synthetic_torques(a, b, 0.0, m, np.array(truth.payload_com_in_bucket_m), truth.offsets_nm)
                    for a, b, m in zip(lifts, tilts, masses)])
    fitted = P.fit_calibration(lifts, tilts, tau[:, 0], tau[:, 1], masses)
    assert fitted.lift_offset_nm == pytest.approx(0.7, abs=1e-9)
    assert fitted.tilt_offset_nm == pytest.approx(-0.3, abs=1e-9)
    np.testing.assert_allclose(fitted.payload_com_in_bucket_m, (0.125, 0.04), atol=1e-9)
    assert fitted.fit["eq8_max_abs_error_kg"] < 1e-9 and fitted.fit["rank"] == 4


def test_calibration_at_one_pose_keeps_the_prior_where_it_cannot_see():
    lift, tilt = -0.1, -0.5
    masses = np.linspace(0.0, 7.0, 8)
    point = np.array([0.13, 0.05])
    tau = np.array([synthetic_torques(lift, tilt, 0.0, m, point) for m in masses])
    fitted = P.fit_calibration(np.full(8, lift), np.full(8, tilt), tau[:, 0], tau[:, 1], masses)
    assert fitted.fit["rank"] == 3
    # the lever arm it sees (horizontal) is right, so eq. 4 is exact at that pose
    np.testing.assert_allclose(P.mass_eq4(lift, tilt, tau[:, 1], fitted), masses, atol=1e-9)


def test_calibration_yaml_round_trip_and_errors(tmp_path):
    calibration = P.PayloadCalibration(0.1, -0.2, (0.11, 0.02), fit={"samples": 3})
    path = calibration.save(tmp_path / "calib.yaml")
    loaded = P.PayloadCalibration.load(path)
    assert loaded == calibration and loaded.fit == {"samples": 3}
    estimator = P.PayloadEstimator.from_yaml(path, method="eq4")
    assert estimator.calibration == calibration
    tau = synthetic_torques(0.0, -0.3, 0.0, 3.0, np.array([0.11, 0.02]), (0.1, -0.2))
    reading = P.PayloadReading(lift_rad=0.0, tilt_rad=-0.3, lift_torque_nm=tau[0], tilt_torque_nm=tau[1])
    assert estimator.mass_kg(reading) == pytest.approx(3.0)
    (tmp_path / "bad.yaml").write_text("format: autoscoop-payload-calibration/1\nlever: 3\n")
    with pytest.raises(ValueError, match="unknown calibration key"):
        P.PayloadCalibration.load(tmp_path / "bad.yaml")
    (tmp_path / "other.yaml").write_text("a: 1\n")
    with pytest.raises(ValueError, match="not an autoscoop payload calibration"):
        P.PayloadCalibration.load(tmp_path / "other.yaml")
    with pytest.raises(ValueError, match="payload_com_in_bucket_m"):
        P.PayloadCalibration(payload_com_in_bucket_m=(0.5, 0.0))
    with pytest.raises(ValueError, match="method"):
        P.PayloadEstimator(method="eq5")


def test_reading_average_is_each_fields_sum_over_its_count():
    average = P.ReadingAverage()
    assert average.take() is None and all(np.isnan(average.latest.as_array()))
    readings = [P.PayloadReading(0.1 * k, -0.3, -20.0 + 0.37 * k, -1.0 - 0.11 * k, 0.01 * k) for k in range(7)]
    for r in readings:
        average.add(r)
    total = np.zeros(5)
    for r in readings:
        total += r.as_array()
    assert average.take().as_array().tolist() == (total / len(readings)).tolist()  # bit for bit
    assert average.take() is None and average.latest == readings[-1]
    # fields arrive on their own (the ROS controller's messages): each is averaged over its own readings
    average.add(P.PayloadReading(1.0, 2.0, 3.0, 4.0, 5.0), ("lift_torque_nm",))
    average.add(P.PayloadReading(9.0, 9.0, 6.0, 8.0, 9.0), ("lift_torque_nm", "tilt_torque_nm"))
    mean = average.take()
    assert (mean.lift_torque_nm, mean.tilt_torque_nm) == (4.5, 8.0)
    assert (mean.lift_rad, mean.chassis_pitch_rad) == (readings[-1].lift_rad, readings[-1].chassis_pitch_rad)
    average.add(readings[0])
    average.restart()
    assert average.take() is None and average.latest == readings[0]


def test_payload_module_does_not_import_the_simulator():
    import subprocess
    import sys

    code = "import sys, autoscoop.core.payload; print('mujoco' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
