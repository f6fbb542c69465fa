"""Sub-commands of the ``autoscoop`` command line, one module each; their shared options are in
:mod:`autoscoop.commands.options`, the checks and writers they share here."""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from filelock import FileLock, Timeout

from autoscoop.core.config import ScoopConfig, load_yaml, overrides_from_yaml, parse_set_args
from autoscoop.core.policy import state_frame_of
from autoscoop.core.safe_files import write_json_atomically


def check_output_file(path: Path, option: str) -> None:
    """Fail now (ValueError, exit 2) if ``path`` could not be written later: a folder, or under a
    non-folder or a read-only folder. Missing folders are fine (:func:`write_json` creates them)."""
    if path.is_dir():
        raise ValueError(f"{option} {path}: is a folder, not a file")
    _check_writable_below(path.parent, path, option, "written")


def check_output_dir(path: Path, option: str) -> None:
    """Fail now (ValueError, exit 2) if folder ``path`` could not be created or written later: a file, or under a
    file or a read-only folder. A missing folder is fine (it is created when written)."""
    if path.exists() and not path.is_dir():
        raise ValueError(f"{option} {path}: is a file, not a folder")
    _check_writable_below(path, path, option, "created")


def _check_writable_below(folder: Path, path: Path, option: str, verb: str) -> None:
    """``folder``'s nearest existing ancestor (itself, if it exists) must be a writable folder, for ``path``."""
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise ValueError(f"{option} {path}: cannot be {verb}, {existing} is not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"{option} {path}: cannot be written, folder {existing} is not writable")


def prepare_records_dir(path: Path, overwrite: bool, option: str = "--records") -> None:
    """Refuse (ValueError, exit 2) a records folder that is a file or is not empty, unless ``overwrite``:
    then its ``episode_*.npz`` records are removed (other files are left, and still refused if any)."""
    if path.exists() and not path.is_dir():
        raise ValueError(f"{option} {path}: is a file, not a folder")
    if not path.is_dir():
        check_output_file(path / "episode_00000.npz", option)
        return
    if overwrite:
        for record in path.glob("episode_*.npz"):
            record.unlink()
    left = sorted(entry.name for entry in path.iterdir() if entry.name != RECORDS_LOCK)
    if left:
        shown = ", ".join(left[:3]) + (", ..." if len(left) > 3 else "")
        hint = ("--overwrite removes only episode_*.npz records; move the other files away"
                if overwrite else "use an empty or new folder, or --overwrite to replace its episode_*.npz records")
        raise ValueError(f"{option} {path}: folder is not empty ({len(left)} entries: {shown}); {hint}")


RECORDS_LOCK = ".autoscoop.lock"
"""the lock file a process writing a records folder holds in it (``filelock``; freed by the OS if it dies)."""


@contextmanager
def records_dir_lock(path: Path, option: str = "--records") -> Iterator[None]:
    """Hold ``path/.autoscoop.lock`` (the folder created) while the block fills records folder ``path``: two
    runs started together cannot both pass the empty-folder check and mix their episodes.

    Raises:
        ValueError: ``path`` is a file or cannot be created (:func:`check_output_dir`), or another process holds
            the lock (not waited for).
    """
    check_output_dir(path, option)
    path.mkdir(parents=True, exist_ok=True)
    lock = FileLock(path / RECORDS_LOCK, timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise ValueError(f"{option} {path}: another autoscoop process is writing records there; wait for it to "
                         "end, or use another folder") from None
    try:
        yield
    finally:
        lock.release()


def warn_if_frame_overridden(args: argparse.Namespace, policy: object, config: ScoopConfig) -> None:
    """Print a warning when ``--set``/``--config`` chose ``sensor.level_with_imu`` and the policy's recorded state
    frame overrides it (the policy runs in the frame it was trained in)."""
    frame = state_frame_of(policy)
    if frame is None or config.sensor.level_with_imu == (frame == "level"):
        return
    chosen = set(parse_set_args(getattr(args, "overrides", [])))
    if getattr(args, "config", None):
        chosen |= set(overrides_from_yaml(args.config))
    if "sensor.level_with_imu" in chosen:
        print(f"warning: sensor.level_with_imu = {str(config.sensor.level_with_imu).lower()} is overridden: the policy "
              f"records its state frame ({frame}), and runs in it", file=sys.stderr)


def config_from_args(args: argparse.Namespace) -> ScoopConfig:
    """The config from ``--config`` and ``--set`` (validated)."""
    config = load_yaml(args.config) if getattr(args, "config", None) else ScoopConfig()
    return config.with_overrides(parse_set_args(getattr(args, "overrides", [])))


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write JSON (NaN written as null), creating the folder; atomically: a failed write (a full disk) leaves
    the previous file as it was."""
    write_json_atomically(path, _nan_to_none(data))


def _nan_to_none(value: Any) -> Any:
    if isinstance(value, float) and math.isnan(value):
        return None
    if isinstance(value, dict):
        return {k: _nan_to_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_nan_to_none(v) for v in value]
    return value
