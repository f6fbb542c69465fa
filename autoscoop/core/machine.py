"""A machine described as data: the schema of ``machine.yaml`` and :func:`load_machine`.

A machine is a folder (``autoscoop/machines/<name>/`` for a shipped one, or any folder of a user's):
``machine.yaml`` (this schema), the MJCF it names, a README saying where each number came from, a licence.
Units are SI throughout (m, kg, rad, s, N, N*m); the file's ``units`` section says so and is checked.

Frames: "chassis frame" x forward from the chassis centre, y left, z up, metres; arm points are (x, z) in
the arm's plane. Both arm joints turn about +y, so a positive angle pitches the part forward-down (a larger
lift angle lowers the arm, a larger tilt angle tips the cutting edge down). "Bucket frame": origin at the
tilt joint, x toward the cutting edge, z toward the mouth.

Every failure is a :class:`MachineError` whose message names the file and the dotted field
(``bucket.mass_kg``, ``sensors[2].unit``) with pydantic's own wording of what is wrong.
"""

from __future__ import annotations

import hashlib
import os
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    field_validator,
)

from autoscoop.core.safe_files import parse_yaml, quote, read_text_bounded

DEFAULT_MACHINE = "komodo"
"""The machine every command uses unless told otherwise."""
MACHINE_FILE = "machine.yaml"
"""Name of the description inside a machine folder."""
MAX_MACHINE_BYTES = 256 * 1024
"""Cap of a machine.yaml autoscoop reads, bytes."""
SCENE_FILE = "scene.xml"
"""The scene beside a machine's MJCF (ground, light, camera, solver) that includes it."""
MACHINE_ENV = "AUTOSCOOP_MACHINE"
"""Environment variable naming the machine a process runs (a shipped name or a folder); ``--machine`` sets it
before anything reads the machine, and worker processes inherit it."""


class MachineError(ValueError):
    """A machine folder or file is not valid; the message names the file and the field."""


def _lo_below_hi(value: tuple[float, float]) -> tuple[float, float]:
    if not value[0] < value[1]:
        raise ValueError(f"the lower limit must be below the upper, got [{value[0]}, {value[1]}]")
    return value


Real = Annotated[float, Field(strict=True, allow_inf_nan=False)]
"""A finite number (an int is taken and becomes a float; a string or a bool is refused)."""
Positive = Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0.0)]
NonNegative = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=0.0)]
PointXZ = tuple[Real, Real]
"""(x, z) in metres."""
Range = Annotated[tuple[Real, Real], AfterValidator(_lo_below_hi)]
"""[lower, upper] with lower < upper."""


class Part(BaseModel):
    """Base of every section: frozen, unknown keys refused."""

    model_config = ConfigDict(frozen=True, extra="forbid")


class Units(Part):
    """The units the file is written in. autoscoop works in SI; any other unit is refused, not converted."""

    length: Literal["m"]
    mass: Literal["kg"]
    angle: Literal["rad"]
    time: Literal["s"]
    force: Literal["N"]
    torque: Literal["N*m"]


class Chassis(Part):
    """The chassis body, a box."""

    size_m: tuple[Positive, Positive, Positive]
    """length (x), width (y), height (z), m."""
    centre_height_m: Positive
    """chassis centre above the ground, m (the chassis frame's origin)."""
    mass_kg: Positive
    com_m: PointXZ
    """centre of mass (x, z) from the chassis centre, m."""


class Wheels(Part):
    """Four wheels, skid-steer."""

    radius_m: Positive
    width_m: Positive
    mass_kg: Positive
    """mass of each wheel, kg."""
    axle_x_m: Range
    """rear and front axle, x from the chassis centre, m (rear < front)."""
    track_m: Positive
    """between the left and right wheel centres, m."""
    ground_friction: Positive
    """wheel-ground sliding friction coefficient, -."""


class Arm(Part):
    """The arm base (fixed to the chassis) and the lift arm (from the lift joint to the tilt joint)."""

    base_from_chassis_m: PointXZ
    """arm base (x, z) from the chassis centre, m."""
    base_mass_kg: Positive
    base_com_m: PointXZ
    """arm base's centre of mass (x, z) from the arm base, m."""
    lift_joint_from_base_m: PointXZ
    """lift joint (x, z) from the arm base, m."""
    tilt_joint_from_lift_joint_m: PointXZ
    """tilt (bucket) joint (x, z) from the lift joint with the arm at lift 0, m."""
    mass_kg: Positive
    com_along_m: Positive
    """arm's centre of mass along the lift joint -> tilt joint line, m."""

    @property
    def length_m(self) -> float:
        """The lift arm's length, lift joint to tilt joint, m."""
        x, z = self.tilt_joint_from_lift_joint_m
        return float((x * x + z * z) ** 0.5)

    @field_validator("com_along_m")
    @classmethod
    def _com_on_the_arm(cls, value: float, info: ValidationInfo) -> float:
        line = info.data.get("tilt_joint_from_lift_joint_m")
        if line is not None:
            length = (line[0] ** 2 + line[1] ** 2) ** 0.5
            if value > length:
                raise ValueError(f"beyond the tilt joint ({length:.4g} m along the arm from the lift joint)")
        return value


class Joint(Part):
    """One arm joint (a hinge about +y)."""

    range_rad: Range
    damping_nms: NonNegative
    """joint damping, N*m*s/rad."""
    armature_kgm2: NonNegative
    """reflected actuator inertia, kg*m^2."""


class Joints(Part):
    """The two arm joints."""

    lift: Joint
    tilt: Joint


class Drive(Part):
    """The wheel motors."""

    max_speed_mps: Positive
    """drive speed limit, forward and back, m/s."""
    wheel_torque_limit_nm: Positive
    """torque bound of each wheel motor, N*m."""


class ArmActuator(Part):
    """A linear actuator seen at its joint: a bounded speed and a bounded torque."""

    max_speed_radps: Positive
    """fastest setpoint motion, rad/s."""
    torque_limit_nm: Positive
    """torque bound at the joint, N*m."""


class Actuators(Part):
    """Drive, lift and tilt."""

    drive: Drive
    lift: ArmActuator
    tilt: ArmActuator


class Bucket(Part):
    """The bucket, in the bucket frame (origin the tilt joint, x to the cutting edge, z toward the mouth)."""

    mass_kg: Positive
    com_from_tilt_joint_m: Positive
    """centre of mass along the tilt joint -> cutting edge line, m."""
    tip_from_tilt_joint_m: Positive
    """cutting edge from the tilt joint, m."""
    mount_pitch_rad: Real
    """pitch-down of the bucket frame from the arm at tilt 0, rad."""
    inner_half_width_m: Positive
    """half the inner width across (y), m."""
    inside_polygon_m: list[PointXZ] = Field(min_length=3)
    """the inner outline in the bucket frame, (x, z) m, clockwise and convex (a particle is inside when it lies
    within it in x-z and within the inner width in y)."""
    capacity_particles: int = Field(strict=True, ge=1, le=10000)
    """how many particles of the machine's nominal pile (``pile.radius_m``) the bucket holds heaped, measured by
    dropping them in one at a time (``autoscoop.sim.capacity.fill_until_overflow``): the volumetric fill's
    denominator."""
    rated_load_kg: Positive
    rated_load_basis: Literal["sae_j818", "stated"] = "sae_j818"
    """how the rated load was set: ``sae_j818`` (the default): at most 50 % of the static tipping load at full
    reach, as SAE J818 and ISO 14397-1 rate a skid-steer, and ``machine check`` holds it to that; ``stated``: as
    its source states it (a paper, a datasheet), and ``machine check`` only requires the machine to stand with
    it at full reach, printing the SAE rating beside it."""

    @field_validator("inside_polygon_m")
    @classmethod
    def _outline_has_area(cls, points: list[tuple[float, float]]) -> list[tuple[float, float]]:
        area = polygon_signed_area(points)
        if abs(area) < 1e-8:
            raise ValueError(f"the outline encloses no area ({abs(area):.3g} m^2)")
        if area > 0:
            raise ValueError("the outline must run clockwise (x to the cutting edge, z toward the mouth): "
                             "reverse the order of its points")
        n = len(points)
        for i in range(n):
            (ax, az), (bx, bz), (cx, cz) = points[i], points[(i + 1) % n], points[(i + 2) % n]
            if (bx - ax) * (cz - bz) - (bz - az) * (cx - bx) > 1e-12:
                raise ValueError(f"the outline must be convex: it turns the other way at point {(i + 1) % n}")
        return points


SENSOR_UNITS = {"joint_position": "rad", "joint_velocity": "rad/s", "joint_torque": "N*m", "position": "m",
                "range": "m", "force": "N"}
"""The unit each sensed quantity must be given in."""


class Sensor(Part):
    """One sensor of the MJCF, named as there."""

    name: str = Field(min_length=1)
    quantity: Literal["joint_position", "joint_velocity", "joint_torque", "position", "range", "force"]
    unit: str

    @field_validator("unit")
    @classmethod
    def _unit_agrees(cls, value: str, info: ValidationInfo) -> str:
        quantity = info.data.get("quantity")
        if quantity is not None and value != SENSOR_UNITS[quantity]:
            raise ValueError(f"disagrees with quantity {quantity!r}, which is in {SENSOR_UNITS[quantity]!r}")
        return value


class Control(Part):
    """The control loop."""

    period_s: Positive
    """time between actions, s."""
    physics_steps_per_period: int = Field(strict=True, ge=1, le=1000)
    """MuJoCo physics steps in one control period."""


class Task(Part):
    """The task's lengths that belong to the machine's size."""

    terminal_dx_m: Real
    """terminal point x from the pile's toe, m."""
    terminal_height_m: Positive
    """terminal point height above the ground, m."""
    target_cycle_time_s: Positive
    """the nominal world's bar on the mean cycle time, s (the stress suite's nominal case: a scoop no slower)."""


class Machine(Part):
    """A loader: what ``machine.yaml`` holds, validated."""

    name: str = Field(min_length=1, pattern=r"^[a-z0-9][a-z0-9_-]*$")
    description: str
    licence: str = Field(min_length=1)
    mjcf: str = Field(min_length=1)
    """the MJCF file, relative to the machine folder."""
    units: Units
    chassis: Chassis
    wheels: Wheels
    arm: Arm
    joints: Joints
    actuators: Actuators
    bucket: Bucket
    sensors: list[Sensor] = Field(min_length=1)
    control: Control
    task: Task
    scene: dict[str, Any] = Field(default_factory=dict)
    """scene settings that differ for this machine from the schema's defaults (the paper's world, sized for the
    Komodo), as dotted config keys (``pile.radius_m: 0.024``); checked against the config schema when loaded."""
    robot_preset: dict[str, list[Real]] = Field(default_factory=dict)
    """ranges of the ``robot`` randomised world that differ for this machine (``randomize`` key names without the
    section: ``particle_radius_m: [0.0495, 0.0525]``)."""
    scripted_scoop: dict[str, Real | int] = Field(default_factory=dict)
    """thresholds of the scripted scoop that differ for this machine (``autoscoop.agents.heuristic.HeuristicParams``
    field names: ``contact_gap_m``, ``exit_height_margin_m``, ...)."""
    default_policy: str | None = None
    """the machine's trained controller, a ``.safetensors`` actor file relative to the folder (what ``--policy
    default`` loads on this machine); None: the machine ships none yet."""

    _folder: Path | None = PrivateAttr(default=None)
    _digest: str = PrivateAttr(default="")

    @field_validator("sensors")
    @classmethod
    def _names_unique(cls, sensors: list[Sensor]) -> list[Sensor]:
        names = [s.name for s in sensors]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"sensor names must be unique: {', '.join(twice)} appear more than once")
        return sensors

    @property
    def folder(self) -> Path | None:
        """The folder it was loaded from (None when built from a dict)."""
        return self._folder

    @property
    def digest(self) -> str:
        """sha256 of the machine.yaml bytes it was loaded from (empty when built from a dict)."""
        return self._digest

    def located(self, folder: Path, digest: str) -> Machine:
        """This machine, recorded as read from ``folder`` with ``digest`` the sha256 of its machine.yaml (for
        :func:`load_machine`)."""
        self._folder, self._digest = folder, digest
        return self

    def mjcf_path(self) -> Path:
        """The MJCF file, resolved against the machine folder."""
        if self._folder is None:
            raise MachineError(f"machine {self.name}: built without a folder, so mjcf {self.mjcf!r} names no file")
        return (self._folder / self.mjcf).resolve()

    def default_policy_path(self) -> Path | None:
        """The machine's trained controller file, resolved against the folder (None when it ships none)."""
        if self.default_policy is None or self._folder is None:
            return None
        return (self._folder / self.default_policy).resolve()


def polygon_signed_area(points: list[tuple[float, float]]) -> float:
    """Shoelace area of an (x, z) outline, m^2: positive counter-clockwise (x right, z up), negative clockwise."""
    n = len(points)
    return 0.5 * sum(points[i][0] * points[(i + 1) % n][1] - points[(i + 1) % n][0] * points[i][1] for i in range(n))


def _where(loc: tuple) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def describe_validation_error(error: ValidationError, source: str, most: int = 8) -> str:
    """One line per problem: ``source: field.path = value: what is wrong``."""
    lines = []
    for record in error.errors()[:most]:
        where = _where(tuple(p for p in record["loc"] if p not in ("function-after", "tuple")))
        shown = record["type"] not in ("missing", "extra_forbidden") and not isinstance(record["input"], dict)
        value = f" = {quote(record['input'], 80)}" if shown else ""
        message = record["msg"].removeprefix("Value error, ")
        if record["type"] == "extra_forbidden":
            message = "unknown key (not part of the machine schema; see docs/machines.md)"
        lines.append(f"{source}: {where or '(top level)'}{value}: {message}")
    more = len(error.errors()) - most
    if more > 0:
        lines.append(f"{source}: ... and {more} more")
    return "\n".join(lines)


def machine_from_dict(data: Any, source: str = MACHINE_FILE) -> Machine:
    """A validated :class:`Machine` from parsed YAML.

    Raises:
        MachineError: naming ``source`` and every field that is wrong.
    """
    if not isinstance(data, dict):
        raise MachineError(f"{source}: must be a mapping of sections, got {type(data).__name__}")
    try:
        return Machine(**{str(k): v for k, v in data.items()})
    except ValidationError as error:
        raise MachineError(describe_validation_error(error, source)) from None


def shipped_machines() -> list[str]:
    """Names of the machines that ship with autoscoop."""
    root = resources.files("autoscoop") / "machines"
    return sorted(p.name for p in root.iterdir() if p.is_dir() and (p / MACHINE_FILE).is_file())


def machine_folder(name_or_dir: str | Path = DEFAULT_MACHINE) -> Path:
    """The folder of a shipped machine (by name) or of a user's (a path to the folder or to its machine.yaml).

    Raises:
        MachineError: neither a shipped name nor a folder with a machine.yaml.
    """
    text = str(name_or_dir)
    shipped = Path(str(resources.files("autoscoop") / "machines" / text))
    if "/" not in text and text not in (".", "..") and (shipped / MACHINE_FILE).is_file():
        return shipped
    path = Path(name_or_dir)
    if path.is_file() and path.name == MACHINE_FILE:
        return path.parent
    if (path / MACHINE_FILE).is_file():
        return path
    known = ", ".join(shipped_machines())
    raise MachineError(f"machine {text!r}: not a shipped machine ({known}) nor a folder with a {MACHINE_FILE}")


def load_machine(name_or_dir: str | Path = DEFAULT_MACHINE) -> Machine:
    """Read and validate a machine.

    Args:
        name_or_dir: a shipped machine's name (``komodo``), a machine folder, or its machine.yaml.

    Returns:
        The validated machine; ``folder`` and ``digest`` say where it came from.

    Raises:
        MachineError: the folder, the file or a field is not valid; the message names it.
    """
    folder = machine_folder(name_or_dir)
    path = folder / MACHINE_FILE
    try:
        text = read_text_bounded(path, MAX_MACHINE_BYTES, "machine file")
        data = parse_yaml(text, f"machine file {path}")
    except ValueError as error:
        raise MachineError(str(error)) from None
    machine = machine_from_dict(data, str(path))
    mjcf = (folder / machine.mjcf).resolve()
    if not mjcf.is_file():
        raise MachineError(f"{path}: mjcf = {machine.mjcf!r}: no such file ({mjcf})")
    return machine.located(folder, hashlib.sha256(text.encode()).hexdigest())


def selected_machine() -> str:
    """The machine this process runs: ``$AUTOSCOOP_MACHINE`` (set by ``--machine``), else the default."""
    return os.environ.get(MACHINE_ENV) or DEFAULT_MACHINE


FILES_BEFORE_MACHINES = DEFAULT_MACHINE
"""The machine of a policy file that records none: files written before machines were recorded are its."""


def machine_record(machine: Machine) -> dict[str, str]:
    """What a policy file records of the machine it was trained on: its name and machine.yaml's sha256."""
    return {"machine": machine.name, "machine_sha256": machine.digest}


def refuse_other_machine(metadata: dict[str, Any], machine: Machine, source: str) -> None:
    """Refuse a policy trained on another machine than the one this process runs.

    A file that records no machine is the default machine's (written before machines were recorded). Only the
    name must agree: a machine.yaml edited since training (another hash) still loads.

    Raises:
        MachineError: naming the file, its machine and this run's.
    """
    recorded = str(metadata.get("machine") or FILES_BEFORE_MACHINES)
    if recorded != machine.name:
        own = recorded if recorded in shipped_machines() else f"DIR (the folder of the machine.yaml named {recorded!r})"
        raise MachineError(f"{source}: a policy for machine {recorded!r}, but this run's machine is {machine.name!r}: "
                           f"pass --machine {own} to run it on its own machine, or adapt or train one for "
                           f"{machine.name!r}")
