"""A sweep's report: ``sweep.csv`` (one row per trial), ``report.md`` (the trials ranked by score, with their
settings) and ``sweep.png`` (the score against each swept setting), from :class:`TrialRow` s.

Nothing here trains or runs Ray; ``autoscoop sweep`` runs the trials (:mod:`autoscoop.training.sweep`) and
calls :func:`write_sweep_report`. The score is the delivered fill of the policy each run kept: the fill
factor (capped at 1) of the successful episodes of its best periodic evaluation, 0 for failures, as
``autoscoop train`` selects its ``policy.*``; fill and success are that evaluation's.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter

from autoscoop.core.safe_files import atomic_output, write_text_atomically
from autoscoop.report.figures import DPI
from autoscoop.training.sweep_results import TrialRow, ranked
from autoscoop.training.sweep_space import Distribution, SweepSpace

CSV_HEAD = ["trial_id"]
CSV_TAIL = ["seed", "score", "fill_factor", "success", "best_episode", "episodes_done", "wall_s", "status", "run_dir",
            "error"]
"""``sweep.csv``'s columns: the trial id, a column per swept setting (its key), then these."""
SCORE_COLOUR, BEST_COLOUR = "#4C72B0", "#C44E52"


@dataclass
class SweepFiles:
    """What :func:`write_sweep_report` wrote."""

    table: Path
    markdown: Path
    figure: Path


def _cell(value: Any, digits: int = 3) -> str:
    if value is None:
        return ""
    if not isinstance(value, float):
        return str(value)
    if math.isnan(value):
        return "n/a"
    return f"{value:.{digits}g}" if 0 < abs(value) < 1e-2 else f"{value:.{digits}f}"  # a learning rate keeps its digits


def write_sweep_csv(rows: Sequence[TrialRow], swept: Sequence[str], path: Path) -> Path:
    """One row per trial, in trial-id order (:data:`CSV_HEAD`, the swept keys, :data:`CSV_TAIL`)."""
    with atomic_output(path) as tmp, open(tmp, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow([*CSV_HEAD, *swept, *CSV_TAIL])
        for row in sorted(rows, key=lambda r: r.trial_id):
            data = row.as_dict()
            writer.writerow([row.trial_id, *(row.settings.get(key, "") for key in swept),
                             *("" if data[key] is None or (isinstance(data[key], float) and math.isnan(data[key]))
                               else data[key] for key in CSV_TAIL)])
    return path


def sweep_table(rows: Sequence[TrialRow], swept: Sequence[str], out_dir: Path | None = None) -> str:
    """The Markdown table: trials ranked by score, best first; run directories relative to ``out_dir``."""
    header = ["rank", "trial", *(f"`{key}`" for key in swept), "seed", "score", "fill factor", "success",
              "best at episode", "episodes", "wall (s)", "status", "run directory"]
    lines = ["| " + " | ".join(header) + " |", "|--:|---|" + "--:|" * (len(swept) + 7) + "---|---|"]
    for rank, row in enumerate(ranked(list(rows)), start=1):
        run_dir = row.run_dir.relative_to(out_dir) if out_dir is not None and row.run_dir.is_relative_to(out_dir) \
            else row.run_dir
        status = row.status if not row.error else f"{row.status}: {row.error[:80]}"
        cells = [str(rank), row.trial_id, *(_cell(row.settings.get(key), 4) for key in swept), str(row.seed),
                 _cell(row.score), _cell(row.fill_factor), _cell(row.success, 2), _cell(row.best_episode),
                 str(row.episodes_done), f"{row.wall_s:.0f}", status, f"`{run_dir}`"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _numeric(values: Sequence[Any]) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def plot_sweep(rows: Sequence[TrialRow], space: SweepSpace, path: Path, title: str = "sweep") -> Path:
    """The score against each swept setting (and the seed, when several), one panel each; the best trial in red.

    Ranges are drawn on a number axis (a log axis for ``loguniform``), lists of numbers too, other values as
    categories. Trials without a score are left out.
    """
    scored = [r for r in rows if not math.isnan(r.score)]
    best = ranked(scored)[0] if scored else None
    panels = [(key, dist, [r.settings.get(key) for r in scored]) for key, dist in space.swept().items()]
    if len(space.seeds) > 1 or not panels:
        panels.append(("seed", Distribution(kind="grid", values=space.seeds), [r.seed for r in scored]))
    fig = Figure(figsize=(3.6 * len(panels) + 0.6, 3.4), layout="constrained")
    axes = fig.subplots(1, len(panels), sharey=True, squeeze=False)[0]
    for ax, (key, dist, values) in zip(axes, panels):
        if dist.kind in ("uniform", "loguniform"):  # the range drawn from
            xs = [float(v) for v in values]
            low, high = dist.values
            if dist.kind == "loguniform":
                ax.set_xscale("log")
                ax.xaxis.set_minor_formatter(NullFormatter())
                ax.set_xlim(low / (high / low) ** 0.05, high * (high / low) ** 0.05)
            else:
                ax.set_xlim(low - 0.05 * (high - low), high + 0.05 * (high - low))
        elif _numeric(dist.values):  # every item of the list, tried or not
            xs = [float(v) for v in values]
            ax.set_xticks([float(v) for v in dist.values], [f"{v:g}" for v in dist.values], fontsize=8)
            span = (max(dist.values) - min(dist.values)) or 1.0
            ax.set_xlim(min(dist.values) - 0.1 * span, max(dist.values) + 0.1 * span)
        else:
            labels = [repr(v) for v in dist.values]
            xs = [labels.index(repr(v)) for v in values]
            ax.set_xticks(range(len(labels)), labels, fontsize=8)
            ax.set_xlim(-0.5, len(labels) - 0.5)
        colours = [BEST_COLOUR if r is best else SCORE_COLOUR for r in scored]
        ax.scatter(xs, [r.score for r in scored], c=colours, s=36, zorder=3)
        ax.set_xlabel(f"{key} ({dist.kind})" if key != "seed" else "seed", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("score: delivered fill of the kept policy", fontsize=9)
    axes[0].set_ylim(-0.02, max(1.0, max((r.score for r in scored), default=1.0)) + 0.02)
    fig.suptitle(title + (f"; best (red): {best.trial_id}, {best.score:.3f}" if best else ""), fontsize=10)
    with atomic_output(path) as tmp:
        fig.savefig(tmp, dpi=DPI)
    return path


def sweep_data(rows: Sequence[TrialRow], space: SweepSpace, info: dict[str, Any]) -> dict[str, Any]:
    """The JSON ``--json`` writes: ``info`` (trials, episodes, wall times ...), the space, the best trial and the
    rows (ranked by score)."""
    order = ranked(list(rows))
    return {**info, "space": space.to_dict(), "swept": list(space.swept()), "fixed": space.fixed(),
            "best": order[0].as_dict() if order and not math.isnan(order[0].score) else None,
            "rows": [row.as_dict() for row in order]}


def write_sweep_report(rows: Sequence[TrialRow], space: SweepSpace, out_dir: Path, title: str = "Sweep",
                       intro: str = "", outro: str = "") -> SweepFiles:
    """Write ``sweep.csv``, ``sweep.png`` and ``report.md`` (intro, the space, the ranked table, outro, the
    figure) into ``out_dir``."""
    swept = list(space.swept())
    table = write_sweep_csv(rows, swept, out_dir / "sweep.csv")
    figure = plot_sweep(rows, space, out_dir / "sweep.png", title=title)
    settings = [f"- `{key}`: {dist.describe()}" for key, dist in {**space.config, **space.hyper}.items()]
    settings.append(f"- seeds: {list(space.seeds)}" + (f"; draws seeded with {space.draw_seed}" if space.draws() else ""))
    parts = [f"# {title}", intro, "Settings (swept ones are columns of the table):", "\n".join(settings),
             "Trials ranked by score, the delivered fill of the policy each run kept (its best periodic "
             f"evaluation, {space.train.eval_episodes} episodes on fixed seeds, as `autoscoop train` keeps "
             "`policy.*`); fill factor and success are that evaluation's:",
             sweep_table(rows, swept, out_dir), outro, f"![score against each swept setting]({figure.name})"]
    markdown = out_dir / "report.md"
    write_text_atomically(markdown, "\n\n".join(p for p in parts if p) + "\n")
    return SweepFiles(table=table, markdown=markdown, figure=figure)
