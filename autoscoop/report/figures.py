"""The paper's figures in our data, drawn from episode records only (matplotlib, no display needed).

* :func:`plot_cycle`: Fig. 9, one scoop: bucket tip trajectory, drive speed, lift and tilt against
  time, the phases (approach, fill, exit) marked;
* :func:`plot_bucket_torque`: Fig. 11, several scoops: tip trajectories and the torque at the bucket
  (tilt) joint against time;
* :func:`plot_by_angle`: Fig. 13, tip trajectories and bucket torque on each pile angle, per controller.

Positions are in the world (pile) frame: x forward from the pile's toe, z up from the ground, metres.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle

from autoscoop.core.config import PileConfig, RewardConfig
from autoscoop.core.phases import PHASES
from autoscoop.core.safe_files import atomic_output
from autoscoop.report.data import Episode

PHASE_COLOURS = {"approach": "#4C72B0", "fill": "#DD8452", "exit": "#55A868"}
CONTROLLER_COLOURS = ("#C44E52", "#4C72B0", "#55A868", "#8172B3", "#937860", "#DA8BC3")
PILE_COLOUR = "#B89B72"
DPI = 120


def controller_colour(name: str, names: Sequence[str]) -> str:
    """A fixed colour per controller, in the order the controllers are listed."""
    return CONTROLLER_COLOURS[list(names).index(name) % len(CONTROLLER_COLOURS)]


def _save(fig: Figure, path: str | Path) -> Path:
    path = Path(path)
    with atomic_output(path) as tmp:  # a failed write leaves the previous figure
        fig.savefig(tmp, dpi=DPI)
    return path


def _draw_pile(ax: Axes, episode: Episode) -> None:
    points = episode.pile_xz()
    if points is None:
        return
    radius = float(episode.meta.get("pile", {}).get("radius_m", PileConfig().radius_m))
    for x, z in points:
        ax.add_patch(Circle((x, z), radius, facecolor=PILE_COLOUR, edgecolor="#7A6548", lw=0.4, alpha=0.35))


def _draw_terminal(ax: Axes, episode: Episode) -> None:
    point = episode.meta.get("terminal_point_m")
    if point is None:
        return
    epsilon = float(episode.meta.get("config", {}).get("reward", {}).get("epsilon_m", RewardConfig().epsilon_m))
    ax.add_patch(Circle(tuple(point), epsilon, fill=False, ls="--", lw=0.8, edgecolor="0.3"))
    ax.plot(*point, marker="*", ms=10, color="0.2", ls="none")


def _trajectory_axes(ax: Axes) -> None:
    ax.axhline(0.0, color="0.4", lw=0.8)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("tip x from the pile's toe (m)")
    ax.set_ylabel("tip height z (m)")
    ax.grid(alpha=0.3)


def _phase_boundaries(episode: Episode) -> tuple[float, float]:
    """Times at which fill and exit began (NaN if they did not)."""
    spans = episode.phases()
    fill, exit_ = spans.times_s["fill"], spans.times_s["exit"]
    return (fill[0] if fill[1] > fill[0] else math.nan), (exit_[0] if exit_[1] > exit_[0] else math.nan)


def _shade_phases(ax: Axes, episode: Episode, label: bool) -> None:
    spans = episode.phases()
    for name in PHASES:
        start, stop = spans.times_s[name]
        if stop > start:
            ax.axvspan(start, stop, color=PHASE_COLOURS[name], alpha=0.12, lw=0)
            if label:
                ax.text((start + stop) / 2, 1.02, name, transform=ax.get_xaxis_transform(),
                        ha="center", va="bottom", fontsize=8, color=PHASE_COLOURS[name])


def _title(episode: Episode) -> str:
    o = episode.outcome
    result = (f"success in {o['cycle_time_s']:.2f} s" if o.get("success") and o.get("cycle_time_s") is not None
              else "no success")
    return (f"{episode.controller} on the {episode.angle_deg:g}° pile, seed {episode.meta.get('seed')}: "
            f"{o.get('mass_kg', math.nan):.2f} kg ({o.get('particles', 0)} particles), {result}")


def plot_cycle(episode: Episode, path: str | Path) -> Path:
    """Fig. 9: (A) the bucket tip's path over the pile, (B) drive speed, (C) lift and (D) tilt against
    time, each coloured or shaded by phase."""
    s = episode.series()
    spans = episode.phases()
    offset = len(s["t"]) - len(s["t_step"])  # 1 when the start is prepended
    fig = Figure(figsize=(11, 6.2), layout="constrained")
    grid = fig.add_gridspec(3, 2, width_ratios=[1.25, 1])
    ax_tip = fig.add_subplot(grid[:, 0])
    _draw_pile(ax_tip, episode)
    _draw_terminal(ax_tip, episode)
    for name in PHASES:
        a, b = spans.steps[name]
        if b > a:  # step i ends at point i + offset; its segment starts one point earlier
            lo, hi = max(a + offset - 1, 0), b + offset
            ax_tip.plot(s["tip_x"][lo:hi], s["tip_z"][lo:hi], "-o", ms=2.5, lw=1.8,
                        color=PHASE_COLOURS[name], label=name)
    ax_tip.plot(s["tip_x"][0], s["tip_z"][0], "s", color="0.2", ms=5, label="start")
    _trajectory_axes(ax_tip)
    ax_tip.legend(loc="upper left", fontsize=8)
    ax_tip.set_title("(A) bucket tip trajectory", fontsize=10, loc="left")
    panels = (("v", "(B) drive speed (m/s)"), ("lift", "(C) lift angle (rad, + lowers the arm)"),
              ("tilt", "(D) tilt angle (rad, + tips the edge down)"))
    axes = []
    for row, (key, title) in enumerate(panels):
        ax = fig.add_subplot(grid[row, 1], sharex=axes[0] if axes else None)
        _shade_phases(ax, episode, label=row == 0)
        ax.plot(s["t"], s[key], "-o", ms=2, lw=1.4, color="0.15")
        ax.set_title(title, fontsize=9, loc="left", pad=12 if row == 0 else 4)
        ax.grid(alpha=0.3)
        axes.append(ax)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(_title(episode), fontsize=11)
    return _save(fig, path)


def plot_bucket_torque(episodes: Sequence[Episode], path: str | Path, max_episodes: int = 5) -> Path:
    """Fig. 11: (A) tip trajectories and (B) the torque at the bucket joint against time for up to
    ``max_episodes`` episodes; ▼ marks where fill began, ▲ where exit began."""
    chosen = list(episodes)[:max_episodes]
    fig = Figure(figsize=(11, 4.4), layout="constrained")
    ax_tip, ax_tq = fig.subplots(1, 2, width_ratios=[1.1, 1])
    _draw_pile(ax_tip, chosen[0])
    _draw_terminal(ax_tip, chosen[0])
    if len(chosen) == 1:
        _shade_phases(ax_tq, chosen[0], label=True)
    colours = [CONTROLLER_COLOURS[i % len(CONTROLLER_COLOURS)] for i in range(len(chosen))]
    for episode, colour in zip(chosen, colours):
        s = episode.series()
        label = f"seed {episode.meta.get('seed')}"
        ax_tip.plot(s["tip_x"], s["tip_z"], "-", lw=1.5, color=colour, label=label)
        ax_tq.plot(s["t_step"], s["tilt_torque"], "-", lw=1.5, color=colour, label=label)
        for when, marker in zip(_phase_boundaries(episode), ("v", "^")):
            if math.isfinite(when):
                k = int(np.argmin(np.abs(s["t"] - when)))
                j = int(np.argmin(np.abs(s["t_step"] - when)))
                ax_tip.plot(s["tip_x"][k], s["tip_z"][k], marker, color=colour, ms=6)
                ax_tq.plot(s["t_step"][j], s["tilt_torque"][j], marker, color=colour, ms=6)
    _trajectory_axes(ax_tip)
    ax_tip.set_title("(A) bucket tip trajectories", fontsize=10, loc="left")
    ax_tq.set_xlabel("time (s)")
    ax_tq.set_ylabel("torque at the bucket joint (N·m)")
    ax_tq.grid(alpha=0.3)
    ax_tq.set_title("(B) bucket-joint torque", fontsize=10, loc="left", pad=12)
    handles = [Line2D([], [], marker="v", ls="none", color="0.3", label="fill begins"),
               Line2D([], [], marker="^", ls="none", color="0.3", label="exit begins")]
    ax_tq.legend(handles=ax_tq.get_legend_handles_labels()[0] + handles, fontsize=8, loc="best")
    first = chosen[0]
    fig.suptitle(f"{first.controller} on the {first.angle_deg:g}° pile: {len(chosen)} scoop"
                 f"{'s' if len(chosen) > 1 else ''}", fontsize=11)
    return _save(fig, path)


def plot_by_angle(groups: dict[tuple[str, float], list[Episode]], path: str | Path,
                  per_group: int = 3) -> Path:
    """Fig. 13: per pile angle (columns), (A) tip trajectories and (B) bucket-joint torque of up to
    ``per_group`` episodes of each controller (colours)."""
    angles = sorted({angle for _, angle in groups})
    controllers = list(dict.fromkeys(name for name, _ in groups))
    fig = Figure(figsize=(4.2 * len(angles) + 0.6, 6.6), layout="constrained")
    axes = np.asarray(fig.subplots(2, len(angles), squeeze=False, sharey="row"))
    for col, angle in enumerate(angles):
        ax_tip, ax_tq = axes[0, col], axes[1, col]
        drawn_pile = False
        for name in controllers:
            episodes = groups.get((name, angle), [])[:per_group]
            colour = controller_colour(name, controllers)
            for i, episode in enumerate(episodes):
                if not drawn_pile:
                    _draw_pile(ax_tip, episode)
                    _draw_terminal(ax_tip, episode)
                    drawn_pile = True
                s = episode.series()
                label = name if i == 0 else None
                ax_tip.plot(s["tip_x"], s["tip_z"], "-", lw=1.3, color=colour, alpha=0.85, label=label)
                ax_tq.plot(s["t_step"], s["tilt_torque"], "-", lw=1.2, color=colour, alpha=0.85, label=label)
        _trajectory_axes(ax_tip)
        ax_tip.set_title(f"(A) {angle:g}° pile: tip trajectories", fontsize=10, loc="left")
        ax_tq.set_title(f"(B) {angle:g}° pile: bucket-joint torque", fontsize=10, loc="left")
        ax_tq.set_xlabel("time (s)")
        ax_tq.grid(alpha=0.3)
    axes[1, 0].set_ylabel("torque at the bucket joint (N·m)")
    handles = [Line2D([], [], color=controller_colour(n, controllers), lw=2, label=n) for n in controllers]
    fig.legend(handles=handles, loc="outside lower center", ncol=len(controllers), fontsize=9)
    fig.suptitle(f"Tip trajectories and bucket torque on {len(angles)} pile angle"
                 f"{'s' if len(angles) > 1 else ''} (up to {per_group} episodes per controller)", fontsize=11)
    return _save(fig, path)
