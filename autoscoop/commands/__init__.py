"""Sub-commands of the ``autoscoop`` command line, one module each, and their shared options."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from autoscoop.core.config import ScoopConfig, load_yaml, parse_set_args


def add_config_args(parser: argparse.ArgumentParser) -> None:
    """``--config FILE.yaml`` and repeatable ``--set key=value``."""
    parser.add_argument("--config", type=Path, help="YAML file with config sections (robot, pile, reward, env)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override one config key, e.g. --set pile.angle_deg=28 (repeatable)")


def config_from_args(args: argparse.Namespace) -> ScoopConfig:
    """The config from ``--config`` and ``--set`` (validated)."""
    config = load_yaml(args.config) if getattr(args, "config", None) else ScoopConfig()
    return config.with_overrides(parse_set_args(getattr(args, "overrides", [])))


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write JSON (NaN written as null), creating the folder."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(_nan_to_none(data), indent=2) + "\n")


def _nan_to_none(value: Any) -> Any:
    if isinstance(value, float) and math.isnan(value):
        return None
    if isinstance(value, dict):
        return {k: _nan_to_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_nan_to_none(v) for v in value]
    return value
