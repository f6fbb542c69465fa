"""``autoscoop payload calibrate RECORDS... --write calib.yaml``: fit the torque-to-mass estimator to records.

The records (``.npz`` episode records, or folders of them) must hold static moments: the arm still,
the bucket clear of the pile, ``mass_in_bucket_kg`` the known payload (counted in simulation, weighed
on the robot). ``autoscoop bench payload --records DIR`` writes such records from static holds.
The fit (torque offsets and the payload's centre of mass in the bucket frame) is written as a small
YAML file that ``autoscoop.core.payload.PayloadEstimator.from_yaml`` (the environment, the ROS node) loads.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from autoscoop.commands import options
from autoscoop.core.payload import PayloadCalibration, fit_calibration
from autoscoop.envs.records import load_record

STATIC_JOINT_STEP_RAD = 0.005
"""Largest change of either joint since the previous step for a step of a moving episode to count as static, rad."""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("payload", help="payload mass from joint torques: calibration",
                                   description=__doc__)
    actions = parser.add_subparsers(dest="payload_action", metavar="ACTION", required=True)
    calibrate = actions.add_parser("calibrate", help="fit torque offsets and the payload lever arm from records",
                                   description=__doc__)
    calibrate.add_argument("records", nargs="+", type=Path, help="episode records (.npz) or folders of them")
    calibrate.add_argument("--write", type=Path, default=Path("payload_calibration.yaml"), metavar="FILE.yaml",
                           help="write the calibration to this YAML file (default payload_calibration.yaml)")
    options.retire_option(calibrate, "--out", "the calibration file to write is --write FILE.yaml (--out is a folder "
                                              "in every command)")
    calibrate.add_argument("--prior", type=Path, metavar="FILE.yaml",
                           help="calibration to start from (its gravity and the lever arm's unobservable direction "
                                "are kept)")
    calibrate.add_argument("--max-joint-step", type=options.NumberIn(0.0, 1.0, "rad"), default=STATIC_JOINT_STEP_RAD, metavar="RAD",
                           help="in records not marked static: use steps whose joints moved less than this "
                                f"since the previous step (default {STATIC_JOINT_STEP_RAD} rad)")
    calibrate.set_defaults(func=run_calibrate)


def record_paths(paths: list[Path]) -> list[Path]:
    """Files as given, folders expanded to their ``*.npz`` (sorted)."""
    out: list[Path] = []
    for path in paths:
        if path.is_dir():
            out.extend(sorted(path.glob("*.npz")))
        elif path.exists():
            out.append(path)
        else:
            raise ValueError(f"record {path} does not exist")
    if not out:
        raise ValueError(f"no records (.npz) in {[str(p) for p in paths]}")
    return out


def static_samples(paths: list[Path], max_joint_step_rad: float = STATIC_JOINT_STEP_RAD) -> dict[str, np.ndarray]:
    """The calibration samples of the records: every step of a record marked ``static``, else the steps
    that are still (joints moved less than ``max_joint_step_rad``), not penetrating, with finite readings.

    Returns:
        Arrays ``lift_rad``, ``tilt_rad``, ``lift_torque_nm``, ``tilt_torque_nm``, ``mass_kg``.
    """
    names = ("lift_rad", "tilt_rad", "lift_torque_nm", "tilt_torque_nm", "mass_in_bucket_kg")
    parts: dict[str, list[np.ndarray]] = {name: [] for name in names}
    for path in paths:
        record = load_record(path)
        a = record.arrays()
        keep = np.all([np.isfinite(a[name]) for name in names], axis=0)
        if not record.meta.get("static", False):
            step = np.maximum(np.abs(np.diff(a["lift_rad"], prepend=np.nan)),
                              np.abs(np.diff(a["tilt_rad"], prepend=np.nan)))
            keep &= (step < max_joint_step_rad) & (a["penetrating"] < 0.5)
        for name in names:
            parts[name].append(a[name][keep])
    out = {name: np.concatenate(values) for name, values in parts.items()}
    out["mass_kg"] = out.pop("mass_in_bucket_kg")
    return out


def run_calibrate(args: argparse.Namespace) -> int:
    paths = record_paths(args.records)
    samples = static_samples(paths, args.max_joint_step)
    n = len(samples["mass_kg"])
    if n < 4:
        raise ValueError(f"only {n} static samples in {len(paths)} record(s); calibration needs at least 4 "
                         "(record static holds, e.g. autoscoop bench payload --records DIR)")
    prior = PayloadCalibration.load(args.prior) if args.prior else None
    calibration = fit_calibration(samples["lift_rad"], samples["tilt_rad"], samples["lift_torque_nm"],
                                  samples["tilt_torque_nm"], samples["mass_kg"], prior=prior)
    fit = dict(calibration.fit, records=[str(p) for p in paths])
    calibration = replace(calibration, fit=fit)
    calibration.save(args.write)
    x, z = calibration.payload_com_in_bucket_m
    print(f"{n} static samples from {len(paths)} record(s), masses {fit['mass_range_kg'][0]:.2f}"
          f"-{fit['mass_range_kg'][1]:.2f} kg")
    print(f"torque offsets      lift {calibration.lift_offset_nm:+.4f} N*m, tilt {calibration.tilt_offset_nm:+.4f} N*m")
    print(f"payload CoM (bucket frame)  x {x:.4f} m, z {z:.4f} m")
    print(f"residual rms        lift {fit['rms_residual_lift_nm']:.4f} N*m, tilt {fit['rms_residual_tilt_nm']:.4f} N*m")
    print(f"max abs error       eq. 8 {fit['eq8_max_abs_error_kg']:.3f} kg, eq. 4 {fit['eq4_max_abs_error_kg']:.3f} kg")
    if fit["rank"] < 4:
        print("note: the samples do not tell the lever arm's two components apart (one bucket angle?); "
              "the unseen one is the prior's. Hold the bucket at several angles to fit both.")
    print(f"wrote {args.write}")
    return 0


def run_payload_bench_cmd(args: argparse.Namespace) -> int:
    """``autoscoop bench payload``: static holds with 0..25 particles and moving scripted scoops."""
    from autoscoop.commands import config_from_args, write_json  # noqa: PLC0415
    from autoscoop.evaluation.payload_bench import run_payload_bench  # noqa: PLC0415

    config = config_from_args(args)
    calibration = PayloadCalibration.load(args.calibration) if args.calibration else None
    result = run_payload_bench(config, episodes=args.episodes, calibration=calibration, records_dir=args.records)
    static, noisy = result["static"], result["static_with_noise"]

    def pair(errors: dict, digits: int = 3) -> str:
        return f"{errors['mean_abs_error_kg']:.{digits}f} / {errors['max_abs_error_kg']:.{digits}f}"

    print(f"static holds, {len(static['rows'])} samples, carried counts {static['counts_covered'][0]}.."
          f"{static['counts_covered'][-1]} (error, kg: mean / max)")
    for name in ("eq8", "eq4"):
        print(f"  {name}  {pair(static[name])}   with {noisy['noise_nm']:g} N*m noise {pair(noisy[name])}"
              f"   vs in-bucket count {pair(static[name + '_vs_in_bucket'])}")
    limit = result["acceptance_eq8_max_abs_error_kg"]
    print(f"  largest rattle of single readings (std of eq. 8): {static['rattle_std_kg_max']:.2f} kg; "
          f"acceptance: eq. 8 max error <= {limit} kg: "
          f"{'pass' if static['eq8']['max_abs_error_kg'] <= limit else 'FAIL'}")
    moving = result["moving"]
    if moving:
        print(f"moving scoops, {moving['episodes']} scripted episodes, {moving['steps']} steps (error, kg: mean / max)")
        for key in ("eq8_mean", "eq8_instant", "eq4_mean", "eq4_instant"):
            cells = "   ".join(f"{where} {pair(moving[key][where], 2)}" for where in
                               ("all_steps", "bucket_clear_of_pile", "last_step", "last_step_vs_carried"))
            print(f"  {key:<12} {cells}")
    if args.records:
        print(f"wrote static-hold records to {args.records}")
    if args.json:
        write_json(args.json, result)
        print(f"wrote {args.json}")
    return 0
