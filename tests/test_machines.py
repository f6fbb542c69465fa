"""Machines as data: the Komodo's machine.yaml, `autoscoop machine check` on bad files, `machine new --scale`."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

from autoscoop.cli import main
from autoscoop.core import kinematics
from autoscoop.core.machine import MACHINE_FILE, load_machine

KOMODO = load_machine("komodo")
KOMODO_DATA = yaml.safe_load((KOMODO.folder / MACHINE_FILE).read_text())
LOADER_XML = KOMODO.mjcf_path()


def write_machine(folder: Path, data: dict | str, mjcf_text: str | None = None) -> Path:
    """A machine folder in ``folder``: ``data`` as machine.yaml (its mjcf the shipped loader unless given)."""
    folder.mkdir(parents=True, exist_ok=True)
    if mjcf_text is not None:
        (folder / "loader.xml").write_text(mjcf_text)
    if isinstance(data, dict):
        data = yaml.safe_dump(data, sort_keys=False)
    (folder / MACHINE_FILE).write_text(data)
    return folder


def komodo_data() -> dict:
    data = copy.deepcopy(KOMODO_DATA)
    data["mjcf"] = str(LOADER_XML)
    return data


def check(folder: Path, capsys: pytest.CaptureFixture) -> tuple[int, str, str]:
    rc = main(["machine", "check", str(folder)])
    out = capsys.readouterr()
    return rc, out.out, out.err


def at(data: dict, dotted: str):
    """The mapping holding the last key of ``dotted``, and that key (list indices as numbers)."""
    *parents, last = [int(p) if p.isdigit() else p for p in dotted.split(".")]
    node = data
    for p in parents:
        node = node[p]
    return node, last


def setting(dotted: str, value):
    def change(data: dict) -> None:
        node, key = at(data, dotted)
        node[key] = value
    return change


def removing(dotted: str):
    def change(data: dict) -> None:
        node, key = at(data, dotted)
        del node[key]
    return change


def _tips_without_the_paper_basis(data: dict) -> None:
    del data["bucket"]["rated_load_basis"]  # the default basis: SAE J818's 50 % of the tipping load


def _duplicate_sensor(data: dict) -> None:
    data["sensors"].append(dict(data["sensors"][0]))


def _missing_mjcf_sensor(data: dict) -> None:
    data["sensors"].append({"name": "load_cell", "quantity": "force", "unit": "N"})


BAD = {
    # field missing
    "missing section": (removing("bucket"), "bucket"),
    "missing bucket mass": (removing("bucket.mass_kg"), "bucket.mass_kg"),
    "missing joint": (removing("joints.lift"), "joints.lift"),
    "missing joint range": (removing("joints.tilt.range_rad"), "joints.tilt.range_rad"),
    "missing units": (removing("units.torque"), "units.torque"),
    "missing terminal point": (removing("task.terminal_height_m"), "task.terminal_height_m"),
    "null section": (setting("arm", None), "arm"),
    # ranges
    "inverted lift range": (setting("joints.lift.range_rad", [0.32, -0.10]), "joints.lift.range_rad"),
    "empty tilt range": (setting("joints.tilt.range_rad", [0.2, 0.2]), "joints.tilt.range_rad"),
    "range of three": (setting("joints.lift.range_rad", [-0.1, 0.0, 0.32]), "joints.lift.range_rad"),
    "inverted axles": (setting("wheels.axle_x_m", [0.17, -0.17]), "wheels.axle_x_m"),
    # masses and sizes
    "zero bucket mass": (setting("bucket.mass_kg", 0), "bucket.mass_kg"),
    "negative arm mass": (setting("arm.mass_kg", -1.65), "arm.mass_kg"),
    "zero chassis mass": (setting("chassis.mass_kg", 0.0), "chassis.mass_kg"),
    "negative wheel mass": (setting("wheels.mass_kg", -0.1), "wheels.mass_kg"),
    "zero rated load": (setting("bucket.rated_load_kg", 0), "bucket.rated_load_kg"),
    "zero wheel radius": (setting("wheels.radius_m", 0), "wheels.radius_m"),
    "arm centre of mass beyond the arm": (setting("arm.com_along_m", 2.0), "arm.com_along_m"),
    # the bucket
    "bucket outline with no area": (setting("bucket.inside_polygon_m", [[0, 0], [0.1, 0], [0.215, 0]]),
                                    "bucket.inside_polygon_m"),
    "bucket outline of two points": (setting("bucket.inside_polygon_m", [[0, 0], [0.215, 0]]), "bucket.inside_polygon_m"),
    "bucket outline counter-clockwise": (setting("bucket.inside_polygon_m", KOMODO_DATA["bucket"]["inside_polygon_m"][::-1]),
                                         "bucket.inside_polygon_m"),
    "bucket outline not convex": (setting("bucket.inside_polygon_m", [[0, 0], [0.05, 0.1], [0.06, 0.01], [0.215, 0],
                                                                       [0.07, -0.06]]), "bucket.inside_polygon_m"),
    "bucket with no width": (setting("bucket.inner_half_width_m", 0.0), "bucket.inner_half_width_m"),
    "bucket outline misses the cutting edge": (setting("bucket.inside_polygon_m", [[0, 0], [0.08, 0.09], [0.19, 0.0],
                                                                                    [0.07, -0.06]]),
                                               "bucket.inside_polygon_m"),
    # what the machine can do
    "unreachable terminal point": (setting("task.terminal_height_m", 0.6), "task.terminal_height_m"),
    "tips at rated load (SAE rating)": (_tips_without_the_paper_basis, "bucket.rated_load_kg"),
    "tips over at rated load": (setting("bucket.rated_load_kg", 12.0), "bucket.rated_load_kg"),
    "bucket starts in the ground": (setting("scene", {"robot.start_lift_rad": 0.32}), "scene: robot.start_lift_rad"),
    "capacity far from the measured": (setting("bucket.capacity_particles", 40), "bucket.capacity_particles"),
    # units
    "lengths in mm": (setting("units.length", "mm"), "units.length"),
    "angles in degrees": (setting("units.angle", "deg"), "units.angle"),
    "joint position sensor in degrees": (setting("sensors.0.unit", "deg"), "sensors[0]"),
    "torque sensor in newtons": (setting("sensors.2.unit", "N"), "sensors[2]"),
    "unknown sensed quantity": (setting("sensors.1.quantity", "temperature"), "sensors[1].quantity"),
    # keys and types
    "unknown top-level key": (setting("colour", "yellow"), "colour"),
    "unknown bucket key": (setting("bucket.volume_l", 5.0), "bucket.volume_l"),
    "unknown joint": (setting("joints.swing", KOMODO_DATA["joints"]["lift"]), "joints.swing"),
    "string for a mass": (setting("bucket.mass_kg", "heavy"), "bucket.mass_kg"),
    "bool for a mass": (setting("arm.mass_kg", True), "arm.mass_kg"),
    "infinite height": (setting("chassis.centre_height_m", float("inf")), "chassis.centre_height_m"),
    "zero physics steps": (setting("control.physics_steps_per_period", 0), "control.physics_steps_per_period"),
    "name with spaces": (setting("name", "my loader"), "name"),
    "duplicate sensor": (_duplicate_sensor, "sensors"),
    # the MJCF
    "MJCF file missing": (setting("mjcf", "no_such_loader.xml"), "mjcf"),
    "sensor not in the MJCF": (_missing_mjcf_sensor, "sensors[10].name"),
    "lift range unlike the MJCF's": (setting("joints.lift.range_rad", [-0.10, 0.30]), "joints.lift.range_rad"),
    "torque limit unlike the MJCF's": (setting("actuators.lift.torque_limit_nm", 120.0), "actuators.lift.torque_limit_nm"),
    "bucket mass unlike the MJCF's": (setting("bucket.mass_kg", 0.9), "bucket.mass_kg"),
    "arm longer than the MJCF's": (setting("arm.tilt_joint_from_lift_joint_m", [0.70, -0.223]),
                                   "arm.tilt_joint_from_lift_joint_m"),
    "bucket wider than the MJCF's side plates": (setting("bucket.inner_half_width_m", 0.26), "bucket.inner_half_width_m"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_a_bad_machine_exits_2_naming_the_field(case, tmp_path, capsys):
    change, field = BAD[case]
    data = komodo_data()
    change(data)
    rc, out, err = check(write_machine(tmp_path / "m", data), capsys)
    assert rc == 2, out + err
    assert field in err, err
    assert "Traceback" not in out + err
    assert "passes" not in out


@pytest.mark.parametrize("text, expected", [
    ("- just\n- a list\n", "must be a mapping"),
    ("name: [unclosed\n", "not valid YAML"),
    ("", "must be a mapping"),
])
def test_a_file_that_is_no_machine_exits_2(text, expected, tmp_path, capsys):
    rc, _, err = check(write_machine(tmp_path / "m", text), capsys)
    assert rc == 2
    assert expected in err


def test_an_mjcf_whose_joint_range_differs_is_named(tmp_path, capsys):
    data = komodo_data()
    data["mjcf"] = "loader.xml"
    xml = LOADER_XML.read_text().replace('range="-0.50 0.90"', 'range="-0.50 1.20"', 1)
    rc, _, err = check(write_machine(tmp_path / "m", data, xml), capsys)
    assert rc == 2
    assert "joints.tilt.range_rad = [-0.5, 0.9] but the MJCF's joint 'tilt' range is [-0.5, 1.2]" in err


def test_side_plates_left_at_the_old_width_are_named(tmp_path, capsys):
    """A wider bucket in machine.yaml whose MJCF side plates stayed where they were: named, with both widths."""
    data = komodo_data()
    data["mjcf"] = "loader.xml"
    xml = LOADER_XML.read_text().replace('mesh="bucket_side" pos="0 0.2400 0"', 'mesh="bucket_side" pos="0 0.2700 0"')
    rc, _, err = check(write_machine(tmp_path / "m", data, xml), capsys)
    assert rc == 2
    assert ("bucket.inner_half_width_m = 0.23 but the MJCF's geom 'bucket_side_left' inner face from the bucket's "
            "centre (y) is 0.26") in err
    assert "bucket_side_right" not in err  # the right plate still agrees


def test_a_folder_without_a_machine_exits_2(tmp_path, capsys):
    rc, _, err = check(tmp_path, capsys)
    assert rc == 2
    assert "komodo" in err  # names the shipped machines


def test_komodo_passes_and_prints_what_it_can_do(capsys):
    rc, out, err = check(Path("komodo"), capsys)
    assert rc == 0, err
    assert "komodo: passes" in out
    assert "heaped 8.91 L" in out
    assert "static tipping load at full reach 9.05 kg" in out


def test_kinematics_takes_its_numbers_from_the_komodo_machine():
    assert kinematics.LIFT_RANGE_RAD == KOMODO.joints.lift.range_rad == (-0.10, 0.32)
    assert kinematics.TILT_RANGE_RAD == KOMODO.joints.tilt.range_rad == (-0.50, 0.90)
    assert kinematics.BUCKET_INSIDE_POLYGON_M.tolist() == [list(p) for p in KOMODO.bucket.inside_polygon_m]
    assert KOMODO.bucket.rated_load_kg == 7.0


@pytest.mark.parametrize("scale", [0.6, 1.5])
def test_a_scaled_machine_passes_check(scale, tmp_path, capsys):
    out = tmp_path / "small"
    assert main(["machine", "new", "small", "--like", "komodo", "--scale", str(scale), "--out", str(out)]) == 0
    capsys.readouterr()
    rc, text, err = check(out, capsys)
    assert rc == 0, err
    small = load_machine(out)
    assert small.name == "small"
    assert small.chassis.size_m == pytest.approx([scale * v for v in KOMODO.chassis.size_m])
    assert small.bucket.rated_load_kg == pytest.approx(scale**3 * KOMODO.bucket.rated_load_kg)
    assert small.actuators.lift.torque_limit_nm == pytest.approx(scale**4 * KOMODO.actuators.lift.torque_limit_nm)
    assert small.joints.lift.range_rad == KOMODO.joints.lift.range_rad
    # the same shape: the tipping share does not change with scale
    assert "rated load 77 % of it" in text
    # its own model name, its capacity as measured (particles settle their own way), a licence to replace
    assert '<mujoco model="small_loader">' in (out / "loader.xml").read_text()
    assert abs(small.bucket.capacity_particles - float(text.split("(mean ")[1].split(")")[0])) <= 0.5
    assert "komodo's licence" in (out / "LICENSE").read_text()
    assert small.licence.startswith("as komodo's until you state yours")


def test_new_refuses_a_folder_that_holds_a_machine(tmp_path, capsys):
    out = write_machine(tmp_path / "m", komodo_data())
    before = (out / MACHINE_FILE).read_text()
    assert main(["machine", "new", "other", "--out", str(out)]) == 2
    assert "already holds" in capsys.readouterr().err
    assert (out / MACHINE_FILE).read_text() == before


def _distinctive_numbers(node) -> set[str]:
    """The floats of a machine.yaml with three or more significant digits, as Python writes them."""
    if isinstance(node, dict):
        return set().union(*(_distinctive_numbers(v) for v in node.values())) if node else set()
    if isinstance(node, list):
        return set().union(*(_distinctive_numbers(v) for v in node)) if node else set()
    if isinstance(node, float) and len(repr(abs(node)).replace(".", "").strip("0")) >= 3:
        return {repr(abs(node))}
    return set()


def test_no_module_outside_the_machines_names_a_komodo_number():
    import re

    numbers = _distinctive_numbers(KOMODO_DATA)
    assert {"0.215", "0.631", "1.65"} <= numbers  # the bucket's length, the arm's, its mass
    package = Path(kinematics.__file__).resolve().parents[1]
    named = [f"{path.relative_to(package)}: {number}" for path in package.rglob("*.py")
             for number in numbers if re.search(rf"(?<![\d.]){re.escape(number)}(?!\d)", path.read_text())]
    assert named == []
