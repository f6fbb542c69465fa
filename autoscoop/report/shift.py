"""A loader's shift on paper: per-cycle and total tables, figures, and the conditions the figures hold under.

Reads what :func:`autoscoop.evaluation.shift.run_shift` returned (one dict per shift); it never simulates.
Masses kg, times s, energy kJ, productivity t/h, energy per tonne kJ/t; x from the pile's toe at the shift's start, m.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from autoscoop.core.safe_files import atomic_output, write_text_atomically
from autoscoop.report.figures import CONTROLLER_COLOURS, DPI
from autoscoop.report.markdown import pm

PROFILE_EVERY = 5
"""The pile's profile is drawn after the first cycle and every this many cycles."""
TOTAL_COLUMNS = (
    ("cycles", "cycles", 1),
    ("delivered_t_per_h", "delivered (t/h)", 4),
    ("energy_kj_per_t", "energy (kJ/t)", 1),
    ("energy_scoop_share", "energy in the scoop (share)", 2),
    ("delivered_kg", "delivered (kg)", 1),
    ("shift_time_s", "shift time (s)", 0),
    ("fill_first5", "fill, first 5", 2),
    ("fill_last5", "fill, last 5", 2),
    ("spillage_share", "spilled on the way (share)", 3),
    ("failed_scoop_share", "failed scoops (share)", 2),
    ("wheel_slip", "wheel slip", 3),
)
"""Columns of the totals table: key in a shift's totals, heading, digits."""
CYCLE_COLUMNS = (
    ("mass_scooped_kg", "scooped (kg)", 2),
    ("mass_delivered_kg", "delivered (kg)", 2),
    ("spilled_on_way_kg", "spilled on the way (kg)", 2),
    ("fill_factor", "fill factor", 2),
    ("volumetric_fill", "volumetric fill", 2),
    ("scoop_time_s", "scoop time (s)", 2),
    ("cycle_time_s", "cycle time (s)", 1),
    ("energy_kj", "energy (kJ)", 3),
    ("wheel_slip", "wheel slip", 3),
)
"""Columns of the per-cycle table: key in a cycle's row, heading, digits."""
DEFINITIONS = (
    "delivered: particles inside the hopper's inner volume when the loader has curled its bucket back after the "
    "dump, counted once and taken away with the hopper",
    "t/h: delivered tonnes per hour of shift time (every cycle's scoop, carry, dump and return)",
    "energy: the actuators' positive mechanical work (force x velocity at the four wheel motors and the lift and "
    "tilt servos, summed over physics steps; braking counts zero), per delivered tonne; in the scoop: the share "
    "of it spent from the scoop's start to its terminal point (the carry, dump and return are the same script for "
    "every policy)",
    "fill factor: mass in the bucket at the scoop's end / rated load; volumetric fill: the particles' solid "
    "volume there / the bucket's capacity",
    "spilled on the way: particles in the bucket at the scoop's end that were neither delivered nor still in the "
    "bucket at the cycle's end",
    "failed scoop: the scoop did not reach the terminal point loaded (success as a single scoop counts it)",
    "wheel slip: 1 - chassis travel along its heading / wheel travel (wheel speed x radius), over the cycle",
)


def _mean_std(values: Sequence[float]) -> tuple[float, float]:
    finite = [v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))]
    if not finite:
        return math.nan, math.nan
    return float(np.mean(finite)), float(np.std(finite))


def group_by_policy(shifts: Sequence[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """Shifts by policy name, in the order the policies first appear."""
    groups: dict[str, list[dict[str, Any]]] = {}
    for shift in shifts:
        groups.setdefault(shift["policy"], []).append(shift)
    return groups


def summarize_totals(shifts: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Mean and standard deviation over shifts of each total (``KEY_mean``, ``KEY_std``), with the seeds."""
    out: dict[str, Any] = {"shifts": len(shifts), "seeds": [s["seed"] for s in shifts]}
    for key, _, _ in TOTAL_COLUMNS:
        out[f"{key}_mean"], out[f"{key}_std"] = _mean_std([s["totals"].get(key, math.nan) for s in shifts])
    out["fill_last5_over_first5"] = (out["fill_last5_mean"] / out["fill_first5_mean"]
                                     if out["fill_first5_mean"] > 0 else math.nan)
    out["conserved"] = all(s["totals"].get("conserved", False) for s in shifts)
    out["completed_all_cycles"] = all(not s["totals"].get("physics_errors") and not s["totals"].get("pile_exhausted")
                                      for s in shifts)
    return out


def cycle_means(shifts: Sequence[dict[str, Any]]) -> list[dict[str, float]]:
    """For each cycle number, each per-cycle column's mean over the shifts that reached it."""
    longest = max((len(s["cycles"]) for s in shifts), default=0)
    rows = []
    for k in range(longest):
        reached = [s["cycles"][k] for s in shifts if len(s["cycles"]) > k]
        rows.append({"cycle": k + 1, **{key: _mean_std([r[key] for r in reached])[0] for key, _, _ in CYCLE_COLUMNS}})
    return rows


def totals_table(groups: dict[str, list[dict[str, Any]]]) -> str:
    """Markdown: one row per policy, each total as mean ± std over its shifts."""
    lines = ["| policy | shifts | " + " | ".join(title for _, title, _ in TOTAL_COLUMNS) + " |",
             "|---|--:|" + "--:|" * len(TOTAL_COLUMNS)]
    for name, shifts in groups.items():
        s = summarize_totals(shifts)
        cells = [pm(s[f"{key}_mean"], s[f"{key}_std"], digits) for key, _, digits in TOTAL_COLUMNS]
        lines.append(f"| {name} | {len(shifts)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def cycle_table(shifts: Sequence[dict[str, Any]]) -> str:
    """Markdown: one row per cycle, each column the mean over the shifts."""
    lines = ["| cycle | " + " | ".join(title for _, title, _ in CYCLE_COLUMNS) + " |",
             "|--:|" + "--:|" * len(CYCLE_COLUMNS)]
    for row in cycle_means(shifts):
        cells = ["n/a" if math.isnan(row[key]) else f"{row[key]:.{digits}f}" for key, _, digits in CYCLE_COLUMNS]
        lines.append(f"| {row['cycle']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def conditions_text(conditions: dict[str, Any]) -> str:
    """The conditions (as ISO 9245 asks a productivity figure to state them) and how the scale model's figures scale."""
    c = conditions
    return "\n".join([
        f"- material: {c['material']}; solid density {c['particle_density_kg_m3']:.0f} kg/m³, loose "
        f"(free particles)",
        f"- pile: {c['pile_particles']} particles, {c['pile_mass_kg']:g} kg, {c['pile_width_m']:.2f} m wide, face slope "
        f"{c['pile_angle_deg']:g}°",
        f"- operation: {c['operation']}",
        f"- haul distance: {c['haul_distance_m']:g} m from the pile's toe to the hopper's centre; top speed "
        f"{c['max_speed_mps']:g} m/s",
        f"- receiver: {c['receiver']}",
        f"- rated load: {c['rated_load_kg']:g} kg",
        "",
        "The loader and its particles are a scale model. At a length scale λ (full size / model) with the same "
        "material density and gravity (Froude scaling), masses grow as λ³ and times as √λ: tonnes per hour grow as "
        "λ^2.5 and energy per tonne as λ (at λ = 10, t/h × 316 and kJ/t × 10). Drive losses, hydraulics and an "
        "engine's efficiency are not modelled: the energy is mechanical work at the actuators, not fuel.",
    ])


def _save(fig: Figure, path: Path) -> Path:
    with atomic_output(path) as tmp:  # a failed write leaves the previous figure
        fig.savefig(tmp, dpi=DPI)
    return path


def plot_fill_and_cycle_time(groups: dict[str, list[dict[str, Any]]], path: Path) -> Path:
    """Fill factor and cycle time per cycle, mean over shifts, one line per policy."""
    fig = Figure(figsize=(9, 5.5), layout="constrained")
    ax_fill, ax_time = fig.subplots(2, 1, sharex=True)
    for colour, (name, shifts) in zip(CONTROLLER_COLOURS * 4, groups.items(), strict=False):
        rows = cycle_means(shifts)
        cycles = [r["cycle"] for r in rows]
        ax_fill.plot(cycles, [r["fill_factor"] for r in rows], "-o", color=colour, label=name)
        ax_time.plot(cycles, [r["cycle_time_s"] for r in rows], "-o", color=colour, label=name)
    ax_fill.set_ylabel("fill factor")
    ax_time.set_ylabel("cycle time (s)")
    ax_time.set_xlabel("cycle")
    for ax in (ax_fill, ax_time):
        ax.grid(alpha=0.3)
    ax_fill.legend(fontsize=8)
    fig.suptitle("Fill and cycle time per cycle (mean over shifts)", fontsize=11)
    return _save(fig, path)


def plot_pile_profiles(groups: dict[str, list[dict[str, Any]]], path: Path) -> Path:
    """The pile's height along the path after the first cycle and every :data:`PROFILE_EVERY` cycles (each policy's
    first shift, one panel per policy)."""
    fig = Figure(figsize=(9, 2.6 * len(groups) + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(groups), 1, sharex=True))
    for ax, (name, shifts) in zip(axes, groups.items(), strict=True):
        cycles = shifts[0]["cycles"]
        shown = sorted({0, *range(PROFILE_EVERY - 1, len(cycles), PROFILE_EVERY), len(cycles) - 1})
        for order, k in enumerate(shown):
            shade = str(0.7 - 0.6 * order / max(len(shown) - 1, 1))
            ax.step(cycles[k]["profile_x_m"], cycles[k]["profile_height_m"], where="mid", color=shade,
                    label=f"after cycle {k + 1}")
        ax.set_title(f"{name} (seed {shifts[0]['seed']})", fontsize=9, loc="left")
        ax.set_ylabel("height (m)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=4)
    axes[-1].set_xlabel("x from the pile's toe at the shift's start (m)")
    return _save(fig, path)


def plot_cumulative_delivered(groups: dict[str, list[dict[str, Any]]], path: Path) -> Path:
    """Delivered mass against shift time, every shift of every policy (one colour per policy)."""
    fig = Figure(figsize=(9, 4.5), layout="constrained")
    ax = fig.subplots()
    for colour, (name, shifts) in zip(CONTROLLER_COLOURS * 4, groups.items(), strict=False):
        for index, shift in enumerate(shifts):
            times = [0.0] + [r["shift_time_s"] for r in shift["cycles"]]
            mass = np.cumsum([0.0] + [r["mass_delivered_kg"] for r in shift["cycles"]])
            ax.step(times, mass, where="post", color=colour, alpha=0.8, label=name if index == 0 else None)
    ax.set_xlabel("shift time (s)")
    ax.set_ylabel("delivered (kg)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)


def write_shift_report(shifts: Sequence[dict[str, Any]], out_dir: str | Path, command: str = "") -> list[Path]:
    """Write ``shift.md`` and its three figures into ``out_dir``; returns the files written.

    Args:
        shifts: one dict per shift (:func:`autoscoop.evaluation.shift.run_shift`), any policies and seeds.
        out_dir: the folder (created if missing).
        command: the command line that made them, quoted in the report.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    groups = group_by_policy(shifts)
    figures = [plot_fill_and_cycle_time(groups, out / "shift_fill_cycle_time.png"),
               plot_pile_profiles(groups, out / "shift_pile_profiles.png"),
               plot_cumulative_delivered(groups, out / "shift_delivered.png")]
    first = shifts[0]
    cycles = max(len(s["cycles"]) for s in shifts)
    parts = [f"# A loader's shift: {', '.join(groups)}", ""]
    if command:
        parts += [f"`{command}`", ""]
    parts += [f"{cycles} cycles per shift; seeds {sorted({s['seed'] for s in shifts})}; autoscoop "
              f"{first['autoscoop_version']}.", "", "## Totals (mean ± std over shifts)", "", totals_table(groups), ""]
    for name, group in groups.items():
        parts += [f"## Per cycle: {name} (mean over {len(group)} shifts)", "", cycle_table(group), ""]
    parts += ["## Conditions", "", conditions_text(first["conditions"]), "", "## Figures", ""]
    parts += [f"![{f.stem}]({f.name})" for f in figures]
    parts += ["", "## Definitions", "", *[f"- {line}" for line in DEFINITIONS], ""]
    markdown = out / "shift.md"
    write_text_atomically(markdown, "\n".join(parts))
    return [markdown, *figures]


def format_totals(shifts: Sequence[dict[str, Any]]) -> str:
    """Plain text for a terminal: each policy's totals, mean ± std over its shifts."""
    groups = group_by_policy(shifts)
    width = max(len(title) for _, title, _ in TOTAL_COLUMNS)
    lines = [f"{'policy':<{width}}  " + "  ".join(f"{name:>18}" for name in groups)]
    summaries = {name: summarize_totals(group) for name, group in groups.items()}
    for key, title, digits in TOTAL_COLUMNS:
        cells = [pm(s[f"{key}_mean"], s[f"{key}_std"], digits).replace("±", "+-") for s in summaries.values()]
        lines.append(f"{title:<{width}}  " + "  ".join(f"{cell:>18}" for cell in cells))
    lines.append(f"{'particles accounted for':<{width}}  " + "  ".join(
        f"{'yes' if s['conserved'] else 'NO':>18}" for s in summaries.values()))
    return "\n".join(lines)
