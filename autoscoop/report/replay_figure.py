"""The figure of a replayed log: commanded and would-have-commanded against time, the watchdog's verdicts marked.

Drawn from the replay's CSV columns (``autoscoop replay``), never from a simulation: one panel each for
the speed (m/s), the lift and the tilt command (rad); the commands sent as a line, the replayed ones as
points; spans where the replayed controller stopped the robot shaded by verdict (``fault``: an input
stale, missing or bad; ``estop``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from autoscoop.core.safe_files import atomic_output

VERDICT_COLOURS = {"fault": "#C44E52", "estop": "#8172B3"}
DPI = 120


def _spans(times: np.ndarray, modes: Sequence[str], mode: str) -> list[tuple[float, float]]:
    """The time spans over which ``modes`` is ``mode`` (each row holds until the next one), s."""
    spans, start = [], None
    for index, current in enumerate(modes):
        if current == mode and start is None:
            start = times[index]
        elif current != mode and start is not None:
            spans.append((start, times[index]))
            start = None
    if start is not None:
        spans.append((start, times[-1] if len(times) else start))
    return spans


def plot_replay(time_s: Sequence[float], sent: dict[str, Sequence[float]], replayed: dict[str, Sequence[float]],
                modes: Sequence[str], path: str | Path, title: str = "") -> Path:
    """Draw the replay figure to ``path`` (written atomically).

    Args:
        time_s: time of each row since the log's start, s.
        sent: per channel (``speed_mps``, ``lift_rad``, ``tilt_rad``), the commands sent (NaN: none).
        replayed: per channel, the replayed controller's commands (NaN: none).
        modes: per row, the replayed controller's mode (``running``, ``idle``, ``fault``, ``estop``).
        path: the image file.
        title: the figure's title.
    """
    times = np.asarray(time_s, dtype=float)
    labels = {"speed_mps": "speed, m/s", "lift_rad": "lift, rad", "tilt_rad": "tilt, rad"}
    fig = Figure(figsize=(9, 7), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for ax, (channel, label) in zip(axes, labels.items()):
        ax.step(times, np.asarray(sent[channel], dtype=float), where="post", color="#4C72B0", label="commanded")
        ax.plot(times, np.asarray(replayed[channel], dtype=float), "o", markersize=3, color="#DD8452",
                label="would have commanded")
        for verdict, colour in VERDICT_COLOURS.items():
            for index, (start, end) in enumerate(_spans(times, modes, verdict)):
                ax.axvspan(start, max(end, start + 1e-3), color=colour, alpha=0.2,
                           label=f"stopped: {verdict}" if index == 0 else None)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel("time since the log's start, s")
    if title:
        fig.suptitle(title)
    path = Path(path)
    with atomic_output(path) as tmp:
        fig.savefig(tmp, dpi=DPI)
    return path
