"""The stress suite's report: a Markdown table and a heat map (case x metric), from :class:`StressRow` s.

Nothing here simulates; ``autoscoop stress`` runs the cases (:mod:`autoscoop.evaluation.stress`)
and calls :func:`write_stress_report`. In the heat map a cell's colour is how far the metric is from
the case's threshold (green: holds, red: does not, the deeper the farther; grey: no threshold on it
in that case); its number is the measured value. Matplotlib is imported by the functions that draw: the
table and verdict serve ``autoscoop stress`` without it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from autoscoop.core.safe_files import atomic_output, write_text_atomically
from autoscoop.envs.definitions import definition_lines
from autoscoop.evaluation.stress import (
    METRIC_NAMES,
    NOMINAL_THRESHOLDS,
    STRESS_THRESHOLDS,
    Check,
    StressRow,
    metric_header,
    unit_suffix,
)

MARGIN_SCALES = {"fill_factor_mean": 0.25, "volumetric_fill_mean": 0.25, "success_rate": 0.25,
                 "reached_rate": 0.25, "cycle_time_mean": 2.0, "overload_rate": 0.05}
"""The margin to a threshold that colours a cell fully (in the metric's unit: fractions, cycle time in s);
an overload rate cannot do better than 0 against 0.05, so 0 is full green."""
STRESS_TERMS = ("fill factor", "volumetric fill", "reached", "success", "cycle time", "overload")
"""the terms ``stress.md`` defines (:mod:`autoscoop.envs.definitions`): those of its table."""
SPREAD_METRICS = ("fill_factor_mean", "volumetric_fill_mean", "cycle_time_mean")
"""Metrics shown as mean ± std (the others are rates)."""
HOLDS_LIGHT, HOLDS_DARK = "#d9f0d3", "#1b7837"
FAILS_LIGHT, FAILS_DARK = "#fddbc7", "#b2182b"
NO_THRESHOLD = "#eeeeee"


@dataclass
class StressFiles:
    """What :func:`write_stress_report` wrote."""

    markdown: Path
    figure: Path


def _std_key(metric: str) -> str:
    return metric.removesuffix("_mean") + "_std"


def format_value(row: StressRow, metric: str, digits: int = 2) -> str:
    """A metric of a row as text: ``mean ± std`` for fills and cycle time, the rate alone otherwise."""
    value = float(row.stats.get(metric, math.nan))
    if math.isnan(value):
        return "n/a"
    if metric in SPREAD_METRICS:
        return f"{value:.{digits}f} ± {float(row.stats.get(_std_key(metric), math.nan)):.{digits}f}"
    return f"{value:.{digits}f}"


def describe_failure(check: Check) -> str:
    """``success 0.07 < 0.9``: what was measured against what was needed."""
    t = check.threshold
    shown = "n/a" if math.isnan(check.measured) else f"{check.measured:.2f}"
    missed = {">=": "<", "<=": ">"}[t.op]
    unit = unit_suffix(t.metric) if shown != "n/a" else ""
    return f"{METRIC_NAMES.get(t.metric, t.metric)} {shown}{unit} {missed} {t.value:g}{unit_suffix(t.metric)}"


def result_text(row: StressRow) -> str:
    """``pass``, or ``FAIL: ...`` naming each threshold that does not hold."""
    failures = row.failures()
    return "pass" if not failures else "FAIL: " + "; ".join(describe_failure(c) for c in failures)


def stress_table(rows: Sequence[StressRow]) -> str:
    """The Markdown table: one row per case, a value in bold where it misses the case's threshold."""
    header = ["case", "world", *(metric_header(m) for m in METRIC_NAMES), "result"]
    lines = ["| " + " | ".join(header) + " |", "|---|---|" + "--:|" * len(METRIC_NAMES) + "---|"]
    for row in rows:
        missed = {c.threshold.metric for c in row.failures()}
        cells = [f"**{format_value(row, m)}**" if m in missed else format_value(row, m) for m in METRIC_NAMES]
        result = "pass" if row.passed else f"**{result_text(row)}**"
        lines.append("| " + " | ".join([row.case.name, row.case.label, *cells, result]) + " |")
    return "\n".join(lines)


def verdict(rows: Sequence[StressRow]) -> str:
    """One sentence: how many cases hold, and which do not."""
    failed = [row.case.name for row in rows if not row.passed]
    if not failed:
        return f"All {len(rows)} cases hold."
    return f"{len(rows) - len(failed)} of {len(rows)} cases hold; not: {', '.join(failed)}."


def _blend(light: str, dark: str, amount: float) -> tuple[float, float, float]:
    from matplotlib.colors import to_rgb  # noqa: PLC0415

    a, b = np.array(to_rgb(light)), np.array(to_rgb(dark))
    return tuple(a + (b - a) * float(np.clip(amount, 0.0, 1.0)))


def margin_colour(margin: float) -> tuple[float, float, float]:
    """The colour of a scaled margin in [-1, 1]: green from light (0, just holds) to dark (1), red below 0."""
    return _blend(HOLDS_LIGHT, HOLDS_DARK, margin) if margin >= 0 else _blend(FAILS_LIGHT, FAILS_DARK, -margin)


def scaled_margin(check: Check) -> float:
    """How far the measured value is on the good side of the threshold, over :data:`MARGIN_SCALES`, in [-1, 1];
    -1 where nothing was measured (NaN). A value exactly at the threshold holds (0)."""
    if math.isnan(check.measured):
        return -1.0
    t = check.threshold
    margin = check.measured - t.value if t.op == ">=" else t.value - check.measured
    scaled = float(np.clip(margin / MARGIN_SCALES.get(t.metric, 0.25), -1.0, 1.0))
    if not check.passed:  # a miss, however small, is red
        return min(scaled, -1e-6)
    return max(scaled, 0.0)


def _legend_cmap():
    from matplotlib.colors import ListedColormap  # noqa: PLC0415

    return ListedColormap([margin_colour(m) for m in np.linspace(-1.0, 1.0, 256)])


def plot_stress(rows: Sequence[StressRow], path: str | Path, title: str = "stress suite") -> Path:
    """The heat map: a row per case, a column per metric and one for the result; the value in each cell."""
    from matplotlib.cm import ScalarMappable  # noqa: PLC0415
    from matplotlib.colors import Normalize, to_rgb  # noqa: PLC0415
    from matplotlib.figure import Figure  # noqa: PLC0415

    from autoscoop.report.figures import DPI  # noqa: PLC0415

    metrics = list(METRIC_NAMES)
    n_rows, n_cols = len(rows), len(metrics) + 1
    colours = np.ones((n_rows, n_cols, 3))
    fig = Figure(figsize=(12.5, 1.6 + 0.55 * n_rows), layout="constrained")
    ax = fig.add_subplot()
    texts = []
    for i, row in enumerate(rows):
        checks = {c.threshold.metric: c for c in row.checks}
        for j, metric in enumerate(metrics):
            check = checks.get(metric)
            colours[i, j] = to_rgb(NO_THRESHOLD) if check is None else margin_colour(scaled_margin(check))
            dark = check is not None and abs(scaled_margin(check)) > 0.6
            text = format_value(row, metric).replace(" ± ", "\n± ")
            texts.append((j, i, text, "white" if dark else ("0.35" if check is None else "black")))
        colours[i, -1] = to_rgb(HOLDS_DARK if row.passed else FAILS_DARK)
        texts.append((n_cols - 1, i, "pass" if row.passed else "FAIL", "white"))
    ax.imshow(colours, aspect="auto", interpolation="nearest")
    for x, y, text, colour in texts:
        ax.text(x, y, text, ha="center", va="center", fontsize=8.5, color=colour,
                fontweight="bold" if x == n_cols - 1 else "normal")
    ax.set_xticks(range(n_cols), [*(metric_header(m) for m in metrics), "result"], fontsize=9)
    ax.xaxis.tick_top()
    ax.set_yticks(range(n_rows), [f"{row.case.label}  [{row.case.name}]" for row in rows], fontsize=9)
    ax.set_xticks(np.arange(-0.5, n_cols), minor=True)
    ax.set_yticks(np.arange(-0.5, n_rows), minor=True)
    ax.grid(which="minor", color="white", lw=2)
    ax.tick_params(which="both", length=0)
    for spine in ax.spines.values():
        spine.set_visible(False)
    ax.set_title(title, fontsize=10, loc="left")
    bar = fig.colorbar(ScalarMappable(Normalize(-1.0, 1.0), _legend_cmap()), ax=ax, shrink=0.8, pad=0.02,
                       ticks=[-1, 0, 1])
    bar.ax.set_yticklabels(["misses by\nfull scale", "at the\nthreshold", "holds by\nfull scale"], fontsize=8)
    bar.set_label("margin to the case's threshold", fontsize=8)
    fig.supxlabel("colour: how far each value is on the good (green) or bad (red) side of its case's threshold; "
                  "full scale 0.25 for fills and rates, 0.05 for overload, 2 s for cycle time; "
                  "grey: no threshold on it in that case", fontsize=8, color="0.3")
    path = Path(path)
    with atomic_output(path) as tmp:  # a failed write leaves the previous figure
        fig.savefig(tmp, dpi=DPI)
    return path


def thresholds_text() -> str:
    """The thresholds, as a Markdown list."""
    def join(thresholds) -> str:
        return ", ".join(str(t) for t in thresholds)

    return (f"- nominal: {join(NOMINAL_THRESHOLDS)};\n"
            f"- every other case: {join(STRESS_THRESHOLDS)}.")


def write_stress_report(rows: Sequence[StressRow], out_dir: str | Path, title: str = "Stress suite",
                        intro: str = "") -> StressFiles:
    """Write ``stress.md`` (thresholds, table, verdict, the heat map) and ``stress.png`` into ``out_dir``."""
    out_dir = Path(out_dir)
    held = sum(row.passed for row in rows)
    figure = plot_stress(rows, out_dir / "stress.png", title=f"{title}: {held} of {len(rows)} cases hold")
    parts = [f"# {title}", intro, "Thresholds:", thresholds_text(), stress_table(rows),
             verdict(rows), f"![stress heat map]({figure.name})", "Definitions:",
             "\n".join(definition_lines(STRESS_TERMS))]
    markdown = out_dir / "stress.md"
    write_text_atomically(markdown, "\n\n".join(p for p in parts if p) + "\n")
    return StressFiles(markdown=markdown, figure=figure)
