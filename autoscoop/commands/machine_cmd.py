"""``autoscoop machine check NAME|DIR`` and ``autoscoop machine new NAME --like komodo --scale S``.

``check`` validates a machine folder: machine.yaml against the schema, the MJCF compiles and its joints,
ranges, masses and limits agree with the YAML, the bucket's heaped capacity, the terminal point within
reach, and the static tipping margin at full reach with the rated load. Every failure names the field
and what is wrong; exit 2 when any fails. ``new`` writes a scaled copy of a machine (Froude scaling:
``autoscoop.core.machine_scaling``) as a starting point. docs/machines.md describes each field.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from dataclasses import fields
from pathlib import Path

import yaml

from autoscoop.agents.heuristic import HeuristicParams
from autoscoop.commands import options
from autoscoop.core import machine_checks
from autoscoop.core.config import ROBOT_PRESET, ScoopConfig
from autoscoop.core.machine import (
    DEFAULT_MACHINE,
    MACHINE_ENV,
    MACHINE_FILE,
    MAX_MACHINE_BYTES,
    SCENE_FILE,
    Machine,
    MachineError,
    load_machine,
    machine_folder,
    machine_from_dict,
)
from autoscoop.core.machine_scaling import scale_machine_data, scale_mjcf
from autoscoop.core.safe_files import parse_yaml, read_text_bounded, write_text_atomically
from autoscoop.sim import machine_model

MJCF_FILE = "loader.xml"
"""Name of the MJCF that ``new`` writes into the new folder."""
LICENSE_FILE = "LICENSE"
"""The licence of a machine folder's numbers and MJCF, beside its machine.yaml."""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("machine", help="check a machine folder, or write a scaled new one",
                                   description=__doc__)
    actions = parser.add_subparsers(dest="machine_action", metavar="ACTION", required=True)
    check = actions.add_parser("check", help="validate a machine folder and print what it can do",
                               description=__doc__)
    check.add_argument("machine", nargs="?", default=DEFAULT_MACHINE, metavar="NAME|DIR",
                       help=f"a shipped machine's name or a machine folder (default {DEFAULT_MACHINE})")
    check.set_defaults(func=run_check)
    new = actions.add_parser("new", help="write a scaled copy of a machine as a starting point",
                             description=__doc__)
    new.add_argument("name", metavar="NAME", help="the new machine's name (lower case letters, digits, - and _)")
    new.add_argument("--like", default=DEFAULT_MACHINE, metavar="NAME|DIR",
                     help=f"the machine to start from (default {DEFAULT_MACHINE})")
    new.add_argument("--scale", type=options.NumberIn(0.1, 10.0), default=1.0, metavar="S",
                     help="length scale factor (masses S^3, torques S^4, times sqrt(S); default 1)")
    new.add_argument("--out", type=Path, metavar="DIR", help="folder to write (must not hold a machine.yaml; "
                                                             "default ./NAME)")
    new.set_defaults(func=run_new)


def check_machine(machine: Machine) -> tuple[list[str], list[str]]:
    """Lines describing the machine, and its problems (empty when it passes)."""
    model = machine_model.load_model(machine)
    problems = machine_model.disagreements(machine, model) + machine_checks.problems(machine)
    cap = machine_checks.capacity(machine)
    top = machine_checks.reach(machine)
    tip = machine_checks.tipping(machine)
    start = machine_checks.start_pose(machine)
    rated = machine.bucket.rated_load_kg
    sae_kg = machine_checks.RATED_SHARE_OF_TIPPING_LOAD * tip.tipping_load_kg
    lines = [
        f"machine            {machine.name}: {machine.description}",
        f"folder             {machine.folder}  (sha256 {machine.digest[:12]})",
        f"mjcf               {machine.mjcf_path()}: {model.nbody - 1} bodies, {model.njnt} joints, "
        f"{model.nu} actuators",
        f"robot mass         {tip.robot_mass_kg:.3f} kg",
        f"bucket capacity    heaped {1000 * cap.heaped_m3:.2f} L, struck {1000 * cap.struck_m3:.2f} L "
        f"(SAE J742 heap at 1:2 over a {cap.strike_length_m:.3f} m strike plane)",
        f"rated load         {rated:g} kg ({rated / cap.heaped_m3 / 1000:.2f} t/m^3 over the heaped capacity; "
        f"basis {machine.bucket.rated_load_basis})",
        f"reach              cutting edge up to {top.tip_height_m:.3f} m (lift {top.lift_rad:.3f}, tilt "
        f"{top.tilt_rad:.3f} rad); terminal point {machine.task.terminal_height_m:g} m high",
        f"start pose         cutting edge {start.tip_height_m:.3f} m, bucket floor {start.lowest_height_m:.3f} m above "
        f"the ground (scene robot.start_lift_rad {start.lift_rad:g}, start_tilt_rad {start.tilt_rad:g})",
        f"tipping            static tipping load at full reach {tip.tipping_load_kg:.2f} kg (load centre "
        f"x {tip.load_centre_x_m:.3f} m, lift {tip.lift_rad:.3f} rad); rated load "
        f"{100 * tip.rated_share:.0f} % of it; SAE J818 / ISO 14397-1 rating (50 %) {sae_kg:.2f} kg",
    ]
    return lines, problems


def run_check(args: argparse.Namespace) -> int:
    try:
        machine = load_machine(args.machine)
        lines, problems = check_machine(machine)
    except MachineError as error:
        print(f"autoscoop machine check: {error}", file=sys.stderr)
        return 2
    print("\n".join(lines))
    source = machine.folder / MACHINE_FILE if machine.folder else machine.name
    for problem in problems:
        print(f"autoscoop machine check: {source}: {problem}", file=sys.stderr)
    for simulated in (measured_capacity, scripted_scoop):
        if problems:
            break
        line, problem = simulated(machine)
        if line:
            print(line)
        if problem:
            problems.append(problem)
            print(f"autoscoop machine check: {source}: {problem}", file=sys.stderr)
    if problems:
        print(f"{machine.name}: {len(problems)} problem(s)", file=sys.stderr)
        return 2
    print(f"{machine.name}: passes")
    return 0


CAPACITY_TOLERANCE_PARTICLES = 2.0
"""How far ``bucket.capacity_particles`` may be from the measured mean before check calls it wrong."""


def _machine_process(machine: Machine, command: list[str]) -> subprocess.CompletedProcess:
    """Run ``command`` (a Python module's arguments) in a process of its own that runs ``machine``."""
    env = {**os.environ, MACHINE_ENV: str(machine.folder)}
    return subprocess.run([sys.executable, "-m", *command], capture_output=True, text=True, check=False, env=env)


def measure_capacity(machine: Machine) -> dict:
    """Drop particles of the machine's nominal pile into its held bucket (``autoscoop.sim.capacity``, seeds 0-2) in
    a process of its own: ``{"radius_m", "seeds", "counts", "mean"}``.

    Raises:
        MachineError: the measurement did not run (its last line of error says why).
    """
    done = _machine_process(machine, ["autoscoop.sim.capacity"])
    if done.returncode != 0:
        why = (done.stderr.strip().splitlines() or [f"exit {done.returncode}"])[-1]
        raise MachineError(f"the bucket's capacity could not be measured: {why}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _drops(measured: dict) -> str:
    """What a :func:`measure_capacity` measured, in words."""
    return (f"{measured['counts']} particles of {measured['radius_m']:g} m on seeds {measured['seeds'][0]}-"
            f"{measured['seeds'][-1]}")


def measured_capacity(machine: Machine) -> tuple[str, str]:
    """:func:`measure_capacity`: the line to print, and the problem ('' when ``bucket.capacity_particles`` is within
    :data:`CAPACITY_TOLERANCE_PARTICLES` of the measured mean)."""
    try:
        measured = measure_capacity(machine)
    except MachineError as error:
        return "", str(error)
    stated = machine.bucket.capacity_particles
    line = f"capacity measured  {_drops(measured)} (mean {measured['mean']:.1f}); machine.yaml says {stated}"
    if abs(stated - measured["mean"]) > CAPACITY_TOLERANCE_PARTICLES:
        return line, (f"bucket.capacity_particles = {stated}: the bucket holds {measured['mean']:.1f} particles heaped "
                      f"(measured {measured['counts']}); set it to {round(measured['mean'])}")
    return line, ""


SCOOP_CHECK_EPISODES = 3
"""Scripted scoops ``machine check`` runs on the machine's nominal pile (seeds 0-2)."""


def scripted_scoop(machine: Machine) -> tuple[str, str]:
    """Run the scripted scoop on the machine's nominal pile in a process of its own (a process runs one machine):
    the line to print, and the problem ('' when at least one of :data:`SCOOP_CHECK_EPISODES` scoops succeeds).
    The machine's ``scene``, ``robot_preset`` and ``scripted_scoop`` sections are checked there too."""
    with tempfile.TemporaryDirectory(prefix="autoscoop-machine-check-") as tmp:
        summary = Path(tmp) / "scoop.json"
        done = _machine_process(machine, ["autoscoop.cli", "eval", "--policy", "heuristic", "--episodes",
                                          str(SCOOP_CHECK_EPISODES), "--json", str(summary), "--allow-empty"])
        if done.returncode != 0 or not summary.is_file():
            why = (done.stderr.strip().splitlines() or [f"exit {done.returncode}"])[-1]
            return "", f"the scripted scoop did not run: {why}"
        result = json.loads(summary.read_text())
    success, fill = result["success_rate"], result["fill_factor_mean"]
    line = (f"scripted scoop     {SCOOP_CHECK_EPISODES} on the nominal pile: success {success:.2f}, fill factor "
            f"{fill:.2f}, cycle {result['cycle_time_mean'] or float('nan'):.2f} s")
    if success == 0.0:
        return line, ("the scripted scoop completes no scoop on the nominal pile: tune its scripted_scoop section or "
                      "the scene's robot.start_lift_rad (docs/machines.md)")
    return line, ""


def run_new(args: argparse.Namespace) -> int:
    source_folder = machine_folder(args.like)
    base = load_machine(source_folder)
    out = args.out or Path(args.name)
    if (out / MACHINE_FILE).exists():
        raise ValueError(f"--out {out}: already holds a {MACHINE_FILE}; choose a new folder")
    data = parse_yaml(read_text_bounded(source_folder / MACHINE_FILE, MAX_MACHINE_BYTES, "machine file"),
                      f"machine file {source_folder / MACHINE_FILE}")
    scaled = scale_machine_data(data, args.scale)
    scaled.update(name=args.name, mjcf=MJCF_FILE,
                  description=f"{base.name} scaled by {args.scale:g} (Froude scaling); describe your machine here",
                  licence=f"as {base.name}'s until you state yours: {base.licence}")
    scaled.pop("default_policy", None)  # a controller belongs to the machine it was trained on
    scaled["task"]["target_cycle_time_s"] = float(format(base.task.target_cycle_time_s * args.scale ** 0.5, ".6g"))
    scaled.update(scaled_world(base, args.scale))
    machine_from_dict(scaled, f"the new {MACHINE_FILE}")  # the scaled numbers must still be a machine
    mjcf = scale_mjcf(read_text_bounded(base.mjcf_path(), MAX_MACHINE_BYTES * 8, "MJCF"), args.scale,
                      f"{args.name}: {base.name}'s MJCF scaled by {args.scale:g} (Froude scaling) by autoscoop "
                      "machine new; machine.yaml holds the numbers", model=f"{args.name}_loader")
    header = (f"# {args.name}: {base.name} scaled by {args.scale:g} (lengths x S, masses x S^3, torques x S^4, "
              "times x sqrt(S)).\n# Field by field: docs/machines.md. Replace the numbers with your machine's "
              "and say where each came from in README.md.\n")
    readme = (f"# {args.name}: where each number came from\n\n"
              f"Written by `autoscoop machine new {args.name} --like {base.name} --scale {args.scale:g}`: every "
              f"number is {base.name}'s (see its README) scaled by Froude scaling with S = {args.scale:g}: lengths "
              "x S, masses x S^3, inertias x S^5, torques x S^4, damping x S^3.5, linear speeds x sqrt(S), "
              "angular speeds x 1/sqrt(S); angles, friction, the control period and the physics step unchanged. "
              "Replace each with your machine's measured or datasheet value and name its source here.\n\n"
              f"Licence: as {base.name}'s ({base.licence}).\n")
    write_text_atomically(out / MJCF_FILE, mjcf)
    write_text_atomically(out / SCENE_FILE, scene_including(base, MJCF_FILE))
    write_text_atomically(out / "README.md", readme)
    write_text_atomically(out / LICENSE_FILE, licence_text(base, args.name))
    write_text_atomically(out / MACHINE_FILE, header + _dump(scaled))  # last: a folder with a machine.yaml is complete
    print(f"wrote {out / MACHINE_FILE}, {out / MJCF_FILE}, {out / SCENE_FILE}, {out / 'README.md'}, "
          f"{out / LICENSE_FILE}")
    # the bucket's capacity in particles does not follow from scaling alone: the particles settle their own way
    measured = measure_capacity(load_machine(out))
    scaled["bucket"]["capacity_particles"] = round(measured["mean"])
    write_text_atomically(out / MACHINE_FILE, header + _dump(scaled))
    print(f"bucket.capacity_particles {round(measured['mean'])}: measured {_drops(measured)}")
    print(f"check it with `autoscoop machine check {out}`")
    return 0


def licence_text(base: Machine, name: str) -> str:
    """The new folder's LICENSE: the base machine's, whose numbers it starts from, until its owner states theirs."""
    base_licence = base.folder / LICENSE_FILE if base.folder else None
    inherited = (read_text_bounded(base_licence, MAX_MACHINE_BYTES, "licence").strip()
                 if base_licence and base_licence.is_file() else base.licence)
    return (f"{name} starts from {base.name}'s numbers and MJCF (scaled), under {base.name}'s licence, quoted below.\n"
            "Replace this file with your machine's licence once its numbers are your own, and say so in machine.yaml's "
            "`licence`.\n\n" + inherited + "\n")


SCALED_UNITS = {"m": 1.0, "kg": 3.0, "s": 0.5}
"""Scene settings that follow the machine's size, by unit: lengths x S, masses x S^3 (the pile's particles scale
with the bucket, so a full bucket holds as many of them), the task's time limits x sqrt(S) (the episode's, the
shift's phases); sensor noise, angles and friction stay."""
FROM_MACHINE_KEYS = {"reward.terminal_dx_m", "reward.terminal_z_m", "reward.rated_load_kg", "env.control_period_s",
                     "env.timestep_s", "pile.settle_s", "sensor.delay_s"}
"""Scene settings not scaled here: those whose default is a field of machine.yaml (scaled there), the pile's
settling time (the simulator's, not the task's) and the sensor link's delay (the link's, not the machine's)."""
SCALED_PRESET = {"particle_mass_kg": 3.0, "particle_radius_m": 1.0, "start_gap_m": 1.0}
"""Ranges of the robot preset that follow the machine's size, with their power of S."""


def _rounded(value: float) -> float:
    return float(format(value, ".6g"))


def scaled_world(base: Machine, scale: float) -> dict[str, dict]:
    """The ``scene``, ``robot_preset`` and ``scripted_scoop`` sections of ``base`` scaled by ``scale``: every
    length and mass setting of its world (the pile's particles, the start gap, the reward's tolerances, the
    shift's hopper), the preset's particle and gap ranges, the scripted scoop's distances (x S), durations in
    control periods (x sqrt(S): the period stays) and angle steps per period (x 1/sqrt(S))."""
    world = ScoopConfig().with_overrides(base.scene)
    scene = {}
    for key in ScoopConfig.dotted_keys():
        section, _, name = key.partition(".")
        field = type(getattr(world, section)).model_fields[name]
        unit = (field.json_schema_extra or {}).get("unit")
        value = getattr(getattr(world, section), name)
        if (unit in SCALED_UNITS and key not in FROM_MACHINE_KEYS and isinstance(value, float) and value != 0.0):
            scene[key] = _rounded(value * scale ** SCALED_UNITS[unit])
    preset = {**ROBOT_PRESET, **{k: tuple(v) for k, v in base.robot_preset.items()}}
    robot_preset = {name: [_rounded(v * scale ** power) for v in preset[name]] for name, power in SCALED_PRESET.items()}
    scripted = {**{f.name: f.default for f in fields(HeuristicParams)}, **base.scripted_scoop}
    scripted_scoop = {}
    for name, value in scripted.items():
        if name.endswith("_m") and not name.startswith("terminal_") and value:
            scripted_scoop[name] = _rounded(value * scale)  # a distance
        elif name.endswith("_steps") and isinstance(value, int):
            scripted_scoop[name] = max(1, round(value * scale ** 0.5))  # a duration, in control periods
        elif name.endswith("_step_rad"):
            scripted_scoop[name] = _rounded(value / scale ** 0.5)  # an angular speed, per control period
    return {"scene": scene, "robot_preset": robot_preset, "scripted_scoop": scripted_scoop}


def scene_including(base: Machine, mjcf_name: str) -> str:
    """The base machine's scene (ground, light, camera, solver) including ``mjcf_name`` instead of its MJCF."""
    text = read_text_bounded(base.mjcf_path().with_name(SCENE_FILE), MAX_MACHINE_BYTES, "scene")
    old = f'<include file="{base.mjcf_path().name}"/>'
    if old not in text:
        raise ValueError(f"{base.mjcf_path().with_name(SCENE_FILE)}: does not include {base.mjcf_path().name}")
    return text.replace(old, f'<include file="{mjcf_name}"/>')


def _dump(data: dict) -> str:
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=120)
