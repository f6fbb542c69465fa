"""A Markdown report (the paper's Table 2 in our data, and the figures) from episode records.

Everything here reads records; nothing simulates. ``autoscoop report RECORDS`` and the end of
``autoscoop demo`` and ``autoscoop compare`` all call :func:`write_report`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from autoscoop.core.config import EnvConfig, PileConfig
from autoscoop.core.safe_files import write_text_atomically
from autoscoop.envs.definitions import definition_lines
from autoscoop.report.data import MANUAL, Episode, group_episodes, summarize_episodes
from autoscoop.report.figures import plot_bucket_torque, plot_by_angle, plot_cycle

REPORT_TERMS = ("fill factor", "volumetric fill", "reached", "success", "cycle time", "spillage")
"""the terms the report defines (:mod:`autoscoop.envs.definitions`): those of its table and the ones they use."""
PAPER_ROWS = (
    # controller, where, mass kg, particles, fill factor, cycle time s
    ("paper: DRL controller", "simulation", "4.4 ± 0.9", "14 ± 3", "0.65", "5"),
    ("paper: DRL controller", "robot, 3 angles", "5.5 ± 1.0", "", "", "5.1 – 7.1"),
    ("paper: manual control", "robot, 32°", "6.1 ± 0.7", "", "", "10"),
)
"""Azulay and Shapiro, IEEE Access 9, 2021 (DOI 10.1109/ACCESS.2021.3056625), Table 2 and Sec. VI (means ± std
as printed there)."""
DEFAULT_TIME_LIMIT_S = EnvConfig().max_episode_s
"""The episode time limit unless the records say otherwise (``env.max_episode_s``); other limits are noted."""


@dataclass
class ReportFiles:
    """What :func:`write_report` wrote."""

    markdown: Path
    figures: list[Path] = field(default_factory=list)


def slug(name: str) -> str:
    """A file-name-safe form of a controller's name."""
    return re.sub(r"[^A-Za-z0-9]+", "-", Path(name).stem if "/" in name else name).strip("-") or "policy"


def pm(mean: float, std: float, digits: int = 2) -> str:
    """``mean ± std`` (``n/a`` when there is no value)."""
    return "n/a" if math.isnan(mean) else f"{mean:.{digits}f} ± {std:.{digits}f}"


def results_table(groups: dict[tuple[str, float], list[Episode]], paper: bool = True) -> str:
    """The Markdown table: one row per (controller, pile angle), then the paper's numbers."""
    lines = ["| controller | pile | episodes | mass in bucket (kg) | particles | fill factor | "
             "cycle time (s) | success | spillage (particles) |",
             "|---|---|--:|--:|--:|--:|--:|--:|--:|"]
    for (name, angle), episodes in sorted(groups.items(), key=lambda item: (item[0][1], item[0][0])):
        s = summarize_episodes(episodes)
        default_limit = math.isnan(s["time_limit_s"]) or s["time_limit_s"] == DEFAULT_TIME_LIMIT_S
        limit = "" if default_limit else f" ({s['time_limit_s']:g} s limit)"
        lines.append(
            f"| {name} | {angle:g}° | {s['episodes']} | {pm(s['mass_kg_mean'], s['mass_kg_std'])} | "
            f"{pm(s['particles_mean'], s['particles_std'], 1)} | {pm(s['fill_factor_mean'], s['fill_factor_std'])} | "
            f"{pm(s['cycle_time_mean'], s['cycle_time_std'])} | {s['success_rate']:.2f}{limit} | "
            f"{pm(s['spillage_mean'], s['spillage_std'], 1)} |")
    if paper:
        for row in PAPER_ROWS:
            name, where, mass, particles, fill, cycle = (f"*{cell}*" if cell else "" for cell in row)
            lines.append(f"| {name} | {where} |  | {mass} | {particles} | {fill} | {cycle} |  |  |")
    return "\n".join(lines)


def write_report(episodes: Sequence[Episode], out_dir: str | Path, title: str = "autoscoop report",
                 intro: str = "", command: str | None = None,
                 cycle_angle_deg: float = PileConfig().angle_deg) -> ReportFiles:
    """Draw the figures and write ``report.md`` into ``out_dir``.

    Args:
        episodes: loaded records (``autoscoop.report.data.load_episodes``).
        out_dir: where ``report.md`` and the PNG figures go.
        title: the report's heading.
        intro: a paragraph under the heading (what was run).
        command: the command line that redraws this report, quoted in it.
        cycle_angle_deg: the pile whose episodes Fig. 9 and Fig. 11 show (else the first pile).

    Returns:
        The files written.
    """
    out_dir = Path(out_dir)
    groups = group_episodes(episodes)
    controllers = list(dict.fromkeys(name for name, _ in groups))
    files = ReportFiles(markdown=out_dir / "report.md")
    sections: list[str] = []

    angles = sorted({angle for _, angle in groups})
    if len(angles) > 1:
        path = plot_by_angle(groups, out_dir / "fig13_tip_by_angle.png")
        files.figures.append(path)
        sections.append("## Tip trajectories and bucket torque per pile angle (paper Fig. 13)\n\n"
                        f"![tip trajectories per pile angle]({path.name})\n")

    for name in controllers:
        mine = {angle: eps for (n, angle), eps in groups.items() if n == name}
        angle = cycle_angle_deg if cycle_angle_deg in mine else sorted(mine)[0]
        chosen = mine[angle]
        suffix = "" if len(controllers) == 1 else f"_{slug(name)}"
        cycle = plot_cycle(chosen[0], out_dir / f"fig9_cycle{suffix}.png")
        torque = plot_bucket_torque(chosen, out_dir / f"fig11_bucket_torque{suffix}.png")
        files.figures += [cycle, torque]
        seed = chosen[0].meta.get("seed")
        sections.append(
            f"## {name} on the {angle:g}° pile\n\n"
            f"One scoop (seed {seed}; paper Fig. 9): the tip's path over the pile, drive speed, lift and tilt; "
            "phases from the record: *approach* until the tip first penetrates the pile, *fill* while it does, "
            "*exit* after.\n\n"
            f"![{name}: one scoop]({cycle.name})\n\n"
            f"The first {min(len(chosen), 5)} scoops (paper Fig. 11): tip trajectories and the torque at the "
            "bucket joint.\n\n"
            f"![{name}: bucket torque]({torque.name})\n")

    manual = [e for e in episodes if e.controller == MANUAL]
    sources = sorted({str(e.meta.get("policy", MANUAL if e in manual else "?")) for e in episodes})
    versions = sorted({str(e.meta.get("autoscoop_version", "?")) for e in episodes})
    provenance = [
        f"- {len(episodes)} episode records; controllers: {', '.join(controllers)}; policy: {', '.join(sources)}",
        f"- piles: {', '.join(f'{a:g}°' for a in angles)}, "
        f"{episodes[0].meta.get('pile', {}).get('n_particles', '?')} particles; autoscoop {', '.join(versions)}",
        "- mean ± standard deviation over episodes; the table notes a time limit other than "
        f"{DEFAULT_TIME_LIMIT_S:g} s",
    ]
    if command:
        provenance.append(f"- redraw from the records, without simulating: `{command}`")

    text = [f"# {title}\n"]
    if intro:
        text.append(intro.strip() + "\n")
    text.append("## Results (paper Table 2)\n")
    text.append(results_table(groups) + "\n")
    text.append("Rows in italics are the paper's (Azulay and Shapiro, IEEE Access 2021); its simulation used "
                "one pile, its robot three (one of them 32°).\n")
    text.append("\n".join(provenance) + "\n")
    text.append("Definitions:\n\n" + "\n".join(definition_lines(REPORT_TERMS)) + "\n")
    text.extend(sections)
    write_text_atomically(files.markdown, "\n".join(text))
    return files
