"""A run directory's files on disk: checkpoints, the safe actor files, ``run.json``, the lock a writing
process holds, and what resuming and fine-tuning read back (CSV truncation, the vetted initial zip)."""

from __future__ import annotations

import json
import os
import shutil
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from filelock import FileLock, Timeout

from autoscoop.agents.loading import zip_is_vouched_for
from autoscoop.agents.policy_files import PolicyFileError, actor_from_sb3, save_actor, sha256_of
from autoscoop.core.version import __version__


def save_safe_actor(model: Any, path: Path, metadata: dict[str, Any]) -> bool:
    """Write the model's actor in the safe format; ``False`` (nothing written) where that format cannot hold it.

    The safe format holds the paper's deterministic actor (DDPG, TD3, SAC's mean); PPO's Gaussian
    policy is kept in ``policy.zip`` only, which its run directory vouches for.
    """
    try:
        actor = actor_from_sb3(model)
    except PolicyFileError:
        return False
    save_actor(actor, path, metadata)
    return True


def actor_meta(info: dict[str, Any], run_dir: Path) -> dict[str, Any]:
    """The metadata every saved actor of a run carries (from its ``run.json``)."""
    return {"algo": info["algo"], "seed": info["seed"], "episodes": info["episodes"],
            "autoscoop_version": __version__, "run": run_dir.name}


def save_checkpoint(model: Any, run_dir: Path, episodes_done: int) -> None:
    """Write model, replay buffer and progress to ``checkpoint/``, atomically (a crash keeps the last one)."""
    tmp = run_dir / "checkpoint.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    model.save(tmp / "model.zip")
    if hasattr(model, "save_replay_buffer"):
        model.save_replay_buffer(tmp / "replay_buffer.pkl")
    (tmp / "state.json").write_text(json.dumps({"episodes_done": episodes_done,
                                                "num_timesteps": int(model.num_timesteps),
                                                "model_sha256": sha256_of(tmp / "model.zip")}))
    final = run_dir / "checkpoint"
    old = run_dir / "checkpoint.old"
    shutil.rmtree(old, ignore_errors=True)
    if final.exists():
        final.rename(old)
    tmp.rename(final)
    shutil.rmtree(old, ignore_errors=True)


def read_checkpoint_state(checkpoint: Path) -> dict[str, Any]:
    """``checkpoint/state.json`` (episodes done, timesteps), after checking ``model.zip`` against its hash.

    Raises:
        ValueError: ``model.zip`` does not match the SHA-256 recorded beside it.
    """
    state = json.loads((checkpoint / "state.json").read_text())
    if sha256_of(checkpoint / "model.zip") != state["model_sha256"]:
        raise ValueError(f"{checkpoint / 'model.zip'} does not match its recorded hash; refusing to load it")
    return state


def load_checkpoint(model_cls: Any, checkpoint: Path, env: Any) -> Any:
    """The model of ``checkpoint/`` on ``env``, with its replay buffer where one was saved.

    Check the zip first (:func:`read_checkpoint_state`): loading it runs pickle.
    """
    model = model_cls.load(checkpoint / "model.zip", env=env, device="cpu")
    if (checkpoint / "replay_buffer.pkl").exists() and hasattr(model, "load_replay_buffer"):
        model.load_replay_buffer(checkpoint / "replay_buffer.pkl")
    return model


def truncate_csv(path: Path, episodes: int) -> None:
    """Keep the header and the first ``episodes`` rows (what the checkpoint had seen)."""
    if not path.exists():
        return
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:1 + episodes]))


def drop_evaluations_after(path: Path, episodes: int) -> None:
    """Keep the header and the evaluations made at or before ``episodes`` (what the checkpoint had seen)."""
    if not path.exists():
        return
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:1] + [line for line in lines[1:] if int(line.split(",", 1)[0]) <= episodes]))


def write_run_json(run_dir: Path, info: dict[str, Any]) -> None:
    """Replace ``run.json`` atomically (a crash leaves the old one or the new one, never half of one)."""
    tmp = run_dir / "run.json.tmp"
    tmp.write_text(json.dumps(info, indent=2) + "\n")
    os.replace(tmp, run_dir / "run.json")


def read_run_json(run_dir: Path) -> dict[str, Any]:
    """A run directory's ``run.json``.

    Raises:
        ValueError: ``run_dir`` has none.
    """
    info_path = run_dir / "run.json"
    if not info_path.exists():
        raise ValueError(f"{run_dir} is not a run directory (no run.json)")
    return json.loads(info_path.read_text())


LOCK_FILE = ".lock"
"""the lock a process writing a run directory holds (``filelock``; the OS frees it if the process dies)."""
HOLDER_FILE = "lock.json"
"""who holds :data:`LOCK_FILE`: PID, host and start time, for the message a second process gets."""


def _holder_text(run_dir: Path) -> str:
    try:
        holder = json.loads((run_dir / HOLDER_FILE).read_text())
        return f"pid {holder['pid']} on {holder['host']}, since {holder['started']}"
    except (OSError, ValueError, KeyError, TypeError):
        return f"holder unknown: {run_dir / HOLDER_FILE} is missing or unreadable"


@contextmanager
def lock_run_dir(run_dir: Path) -> Iterator[None]:
    """Hold ``run_dir/.lock`` while the block writes the run directory (which must exist), released on any exit.

    The lock is not waited for: a run directory has one writer. The holder's PID, host and start time
    are written to ``run_dir/lock.json`` while it is held.

    Raises:
        ValueError: another process holds the lock (the message names the directory and that process).
    """
    run_dir = Path(run_dir)
    lock = FileLock(run_dir / LOCK_FILE, timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise ValueError(f"{run_dir} is being written by another autoscoop process ({_holder_text(run_dir)}); "
                         f"wait for it to end, or stop it, before training into this directory") from None
    holder = run_dir / HOLDER_FILE
    try:
        tmp = run_dir / (HOLDER_FILE + ".tmp")
        tmp.write_text(json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                                   "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}) + "\n")
        os.replace(tmp, holder)
        yield
    finally:
        holder.unlink(missing_ok=True)
        lock.release()


def init_model_zip(run_dir: Path, algo: str, trust: bool) -> Path:
    """The SB3 zip of a finished run to fine-tune from, after checking that it may be loaded.

    Raises:
        ValueError: not a run directory, another algorithm, or a zip the run does not vouch for
            (its ``run.json`` records the SHA-256) and ``trust`` is false.
    """
    run_dir = Path(run_dir)
    zip_path = run_dir / "policy.zip"
    if not (run_dir / "run.json").is_file() or not zip_path.is_file():
        raise ValueError(f"--init {run_dir}: not a training run directory (needs run.json and policy.zip)")
    source_algo = json.loads((run_dir / "run.json").read_text()).get("algo")
    if source_algo != algo:
        raise ValueError(f"--init {run_dir}: that run trained {source_algo!r}, this one trains {algo!r}")
    if not trust and not zip_is_vouched_for(zip_path):
        raise ValueError(f"--init {run_dir}: its run.json does not vouch for policy.zip (SHA-256), and loading "
                         "a zip runs pickle; pass --trust if you trust where it came from")
    return zip_path


def load_init_weights(model: Any, zip_path: Path, sha256: str) -> None:
    """Copy the networks (actor, critic and their targets) of a vetted SB3 zip into ``model``."""
    if sha256_of(zip_path) != sha256:
        raise ValueError(f"{zip_path} changed since this run started from it (SHA-256); refusing to load it")
    source = type(model).load(zip_path, device="cpu")
    model.policy.load_state_dict(source.policy.state_dict())
