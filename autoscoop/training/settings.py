"""The algorithm's settings: its YAML from ``autoscoop/training/hyperparams/`` and ``--hyper`` overrides."""

from __future__ import annotations

from importlib import resources
from typing import Any

import yaml

from autoscoop.agents.algorithms import ALGORITHMS


def load_hyperparams(algo: str) -> dict[str, Any]:
    """The algorithm's YAML from the package (``autoscoop/training/hyperparams/ALGO.yaml``)."""
    if algo not in ALGORITHMS:
        raise ValueError(f"--algo {algo!r} is not offered; choose one of {sorted(ALGORITHMS)}")
    text = (resources.files("autoscoop") / "training" / "hyperparams" / f"{algo}.yaml").read_text()
    return yaml.safe_load(text)


def with_hyper_overrides(spec: dict[str, Any], overrides: dict[str, str]) -> dict[str, Any]:
    """The algorithm's settings with ``section.key=value`` overrides (``hyperparams.learning_rate=3e-4``,
    ``noise.sigma_start=0.05``); only keys the YAML already has, values parsed as YAML scalars of the same type.

    Raises:
        ValueError: an unknown key, or a value of another type than the YAML's.
    """
    out = {name: dict(section) if isinstance(section, dict) else section for name, section in spec.items()}
    for dotted, text in overrides.items():
        section, _, key = dotted.partition(".")
        if not isinstance(out.get(section), dict) or key not in out[section]:
            known = sorted(f"{name}.{k}" for name, sec in out.items() if isinstance(sec, dict) for k in sec)
            raise ValueError(f"--hyper {dotted}: not a setting of this algorithm; known: {', '.join(known)}")
        old = out[section][key]
        value = yaml.safe_load(text)
        if isinstance(old, float) and not isinstance(value, bool):
            try:  # YAML reads 3e-4 as a string
                value = float(text)
            except ValueError:
                pass
        if type(value) is not type(old):
            raise ValueError(f"--hyper {dotted}={text}: expected a {type(old).__name__} like {old!r}")
        out[section][key] = value
    return out
