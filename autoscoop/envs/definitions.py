"""The terms every report defines, in the words of how the environment measures them.

The environment counts them (:class:`autoscoop.envs.scoop.ScoopEnv`'s ``info``) and
:class:`autoscoop.envs.outcome.EpisodeOutcome` carries them; the eval table, ``stress.md`` and the
``report.md`` of ``demo``, ``compare`` and ``report`` print these lines, and docs/definitions.md carries
them as they are (a test checks it). Numbers are the config's defaults, each named by its key.
"""

from __future__ import annotations

from collections.abc import Iterable

from autoscoop.core.config import ScoopConfig
from autoscoop.sim.capacity import CAPACITY_M3, CAPACITY_PARTICLES, NOMINAL_RADIUS_M


def _definitions(config: ScoopConfig) -> dict[str, str]:
    reward, scoop = config.reward, config.scoop
    return {
        "fill factor": "the mass of the particles inside the bucket when the episode ends ÷ the rated load "
                       f"(`reward.rated_load_kg`, {reward.rated_load_kg:g} kg)",
        "volumetric fill": "the solid volume of the particles inside the bucket when the episode ends ÷ the bucket's "
                           f"heaped capacity ({CAPACITY_PARTICLES} particles of {NOMINAL_RADIUS_M:g} m radius, "
                           f"{CAPACITY_M3 * 1000:.1f} L of particle volume)",
        "reached": f"the tip came within `reward.epsilon_m` ({reward.epsilon_m:g} m) of the terminal point, in the "
                   f"arm's plane, before the time limit (`env.max_episode_s`, {config.env.max_episode_s:g} s), "
                   "loaded or not; it ends the episode",
        "success": "reached loaded: on reaching the terminal point, the fill factor or the volumetric fill, "
                   f"whichever is higher, is at least `scoop.min_fill` ({scoop.min_fill:g})",
        "cycle time": "seconds from the episode's start until success; an episode without success has none, and "
                      "means are over the successful episodes only",
        "overload": f"the fill factor at the end is above `scoop.overload_fill` ({scoop.overload_fill:g})",
        "spillage": "particles that were inside the bucket at some moment of the episode and are not at its end",
    }


DEFINITIONS: dict[str, str] = _definitions(ScoopConfig())
"""term -> its definition, with the default config's numbers."""


def definition_lines(terms: Iterable[str] | None = None, markdown: bool = True) -> list[str]:
    """One line per term (default: every term of :data:`DEFINITIONS`, in its order): ``- **term**: definition``
    in Markdown, ``term: definition`` in plain text (ASCII: ``/`` for ``÷``, no backticks).

    Raises:
        KeyError: a term that is not defined here.
    """
    chosen = list(DEFINITIONS) if terms is None else list(terms)
    if markdown:
        return [f"- **{term}**: {DEFINITIONS[term]}" for term in chosen]
    return [f"{term}: {DEFINITIONS[term].replace('`', '').replace('÷', '/')}" for term in chosen]
