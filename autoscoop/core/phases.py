"""The three phases of a scoop (paper Sec. VI), read from what happened, not from a controller.

* **approach**: from the start until the bucket tip first penetrates the pile (paper eq. 7);
* **fill**: from then until the tip last penetrates it;
* **exit**: after that, until the episode ends.

An episode whose tip never penetrates the pile is all approach. Numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PHASES = ("approach", "fill", "exit")


@dataclass(frozen=True)
class PhaseSpans:
    """Where each phase starts and ends, as step indices (``[start, stop)``) and as times (s)."""

    steps: dict[str, tuple[int, int]]
    times_s: dict[str, tuple[float, float]]

    def at_step(self, index: int) -> str:
        """The phase that step ``index`` belongs to."""
        for name, (start, stop) in self.steps.items():
            if start <= index < stop:
                return name
        return PHASES[-1] if index >= 0 else PHASES[0]


def phase_spans(penetrating: np.ndarray, time_s: np.ndarray, start_s: float = 0.0) -> PhaseSpans:
    """Split an episode into approach, fill and exit.

    Args:
        penetrating: (n,) per step, whether the tip penetrated the pile after the step (0/1 or bool).
        time_s: (n,) time at the end of each step, s.
        start_s: time of the episode's start, s.

    Returns:
        The phases' step ranges and time ranges; a phase that did not happen has an empty range.
        Step ``i`` covers the time from the end of step ``i - 1`` (or ``start_s``) to ``time_s[i]``.
    """
    hits = np.flatnonzero(np.asarray(penetrating, dtype=bool))
    n = len(time_s)
    first, last = (int(hits[0]), int(hits[-1]) + 1) if len(hits) else (n, n)
    steps = {"approach": (0, first), "fill": (first, last), "exit": (last, n)}
    edges = np.concatenate([[start_s], np.asarray(time_s, dtype=float)])
    times = {name: (float(edges[a]), float(edges[b])) for name, (a, b) in steps.items()}
    return PhaseSpans(steps=steps, times_s=times)


def phase_now(penetrated_before: bool, penetrating_now: bool) -> str:
    """The phase at a moment, while the episode runs: what :func:`phase_spans` will say afterwards,
    except that a pause in penetration during the fill already reads as exit."""
    if penetrating_now:
        return "fill"
    return "exit" if penetrated_before else "approach"
