"""A run directory's files on disk: checkpoints, the safe actor files, ``run.json``, the lock a writing
process holds, and what resuming and fine-tuning read back (CSV truncation, the vetted initial zip).

A checkpoint (``checkpoint/``) holds no pickle: ``state.json`` (format, the run's bookkeeping, the model's
counters and how its tensors nest, each file's SHA-256), ``tensors.safetensors``, ``replay_buffer.npz`` and
``best/`` (a copy of the best policy so far); see :mod:`autoscoop.training.model_state`."""

from __future__ import annotations

import csv
import math
import os
import shutil
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from filelock import FileLock, Timeout

from autoscoop.agents.critic_files import name_kept_actor
from autoscoop.agents.loading import refuse_untrusted_zip
from autoscoop.agents.policy_files import (
    PolicyFileError,
    actor_from_sb3,
    actor_into_sb3,
    load_actor,
    save_actor,
    sha256_of,
)
from autoscoop.core import kinematics
from autoscoop.core.machine import machine_record, refuse_other_machine
from autoscoop.core.safe_files import quote, read_json, read_yaml, write_json_atomically, write_text_atomically
from autoscoop.core.version import __version__
from autoscoop.training.model_state import BUFFER_FILE, TENSORS_FILE, load_model_state, save_model_state


def save_safe_actor(model: Any, path: Path, metadata: dict[str, Any], target: bool = False) -> bool:
    """Write the model's actor (with ``target``, its target actor) in the safe format; ``False`` (nothing
    written) where that format cannot hold it.

    The safe format holds the paper's deterministic actor (DDPG, TD3, SAC's mean); PPO's Gaussian
    policy is kept in ``policy.zip`` only, which its run directory vouches for.
    """
    try:
        actor = actor_from_sb3(model, target=target)
    except PolicyFileError:
        return False
    save_actor(actor, path, {**metadata, "target_actor": True} if target else metadata)
    return True


def actor_meta(info: dict[str, Any], run_dir: Path) -> dict[str, Any]:
    """The metadata every saved actor of a run carries (from its ``run.json``)."""
    return {"algo": info["algo"], "seed": info["seed"], "episodes": info["episodes"],
            "autoscoop_version": __version__, "run": run_dir.name,
            "state_frame": info.get("state_frame", "chassis")}


MAX_STATE_BYTES = 16 << 20
"""cap of a checkpoint's ``state.json``, bytes."""
CHECKPOINT_FORMAT = "autoscoop-checkpoint/2"
"""``state.json``'s ``format``: tensors in safetensors, the replay buffer in ``.npz``, the rest JSON; no pickle."""
CHECKPOINT_DIRS = ("checkpoint", "checkpoint.tmp", "checkpoint.old")
"""the checkpoint, the next one being written, the previous one while they are swapped (a kill -9 can leave any)."""
BEST_FILES = ("policy.zip", "policy.safetensors", "policy.json")
"""the best-evaluated policy so far, copied into the checkpoint's ``best/`` (a resumed run starts from it)."""
BOOKKEEPING = ("episodes_done", "evaluations_done", "wall_s", "best_score", "best_episode")
"""what a checkpoint records of the run: episodes and evaluations done (rows of ``episodes.csv`` and
``evaluations.csv``), wall time so far (s), the best evaluation score and its episode (``None`` before one)."""
CRITIC_FILE = "critic.safetensors"
"""a run's critic(s) at the end of training, beside ``critic.json`` (:mod:`autoscoop.agents.critic_files`)."""
RUN_OUTPUTS = ("episodes.csv", "evaluations.csv", *BEST_FILES, "last.safetensors", "last.json", CRITIC_FILE,
               "critic.json", "learning_curve.png",
               "evaluated", "tb", "selection.json", *CHECKPOINT_DIRS)
"""what training writes into a run directory after its settings (cleared when a run restarts from episode 0)."""


def save_checkpoint(model: Any, run_dir: Path, bookkeeping: dict[str, Any], algo: str) -> None:
    """Write the model, its replay buffer, the best policy so far and ``bookkeeping`` (:data:`BOOKKEEPING`) to
    ``checkpoint/``, atomically: a crash, kill -9 included, keeps the last complete one."""
    tmp = run_dir / "checkpoint.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    model_state = save_model_state(model, tmp)
    best = [name for name in BEST_FILES if (run_dir / name).is_file()]
    if best:
        (tmp / "best").mkdir()
        for name in best:
            shutil.copyfile(run_dir / name, tmp / "best" / name)
    files = {str(path.relative_to(tmp)): sha256_of(path) for path in sorted(tmp.rglob("*")) if path.is_file()}
    state = {"format": CHECKPOINT_FORMAT, "algo": algo, **{key: bookkeeping[key] for key in BOOKKEEPING},
             "model": model_state, "files": files}
    _write_json_atomically(tmp / "state.json", state)  # last: a checkpoint folder with state.json is complete
    final = run_dir / "checkpoint"
    old = run_dir / "checkpoint.old"
    shutil.rmtree(old, ignore_errors=True)
    if final.exists():
        final.rename(old)
    tmp.rename(final)
    shutil.rmtree(old, ignore_errors=True)


def _write_json_atomically(path: Path, data: dict[str, Any]) -> None:
    write_json_atomically(path, data, indent=1)


def find_checkpoint(run_dir: Path, algo: str) -> tuple[Path, dict[str, Any]] | None:
    """The newest complete checkpoint of ``run_dir`` (of :data:`CHECKPOINT_DIRS`, the one with the most
    episodes) and its checked ``state.json``; ``None`` where there is none.

    Raises:
        ValueError: a checkpoint that cannot be vouched for (:func:`read_checkpoint_state`).
    """
    found = [(folder, read_checkpoint_state(folder, algo)) for folder in (run_dir / name for name in CHECKPOINT_DIRS)
             if (folder / "state.json").is_file()]
    return max(found, key=lambda item: item[1]["episodes_done"]) if found else None


def read_checkpoint_state(checkpoint: Path, algo: str) -> dict[str, Any]:
    """``checkpoint/state.json``, after checking that the folder holds only what autoscoop writes there, unchanged.

    Nothing is loaded that could run code: a checkpoint of an older autoscoop (pickles: ``model.zip``,
    ``replay_buffer.pkl``) and any file this version does not write are refused, not opened.

    Raises:
        ValueError: another format or algorithm, a malformed state, a file too many, missing or changed
            (SHA-256); the message names the file.
    """
    path = checkpoint / "state.json"
    state = read_json(path, "checkpoint state", MAX_STATE_BYTES)
    if not isinstance(state, dict) or state.get("format") != CHECKPOINT_FORMAT:
        found = state.get("format") if isinstance(state, dict) else None
        raise ValueError(f"{path}: checkpoint format {found!r}, expected {CHECKPOINT_FORMAT!r}. Older checkpoints keep "
                         f"the model and replay buffer as pickles, which resume does not load: remove {checkpoint} "
                         "to restart the run from episode 0, or start a new run")
    if state.get("algo") != algo:
        raise ValueError(f"{path}: a checkpoint of {state.get('algo')!r}, the run trains {algo!r}")
    _check_bookkeeping(state, path)
    _check_files(checkpoint, state.get("files"))
    return state


def _check_bookkeeping(state: dict[str, Any], path: Path) -> None:
    counts = [state.get(key) for key in ("episodes_done", "evaluations_done")]
    if not all(_is_whole(n) and n >= 0 for n in counts):
        raise ValueError(f"{path}: episodes_done and evaluations_done must be whole numbers, 0 or more; got {counts}")
    wall_s, best_score, best_episode = state.get("wall_s"), state.get("best_score"), state.get("best_episode")
    if not (_is_number(wall_s) and wall_s >= 0):
        raise ValueError(f"{path}: wall_s must be a number of seconds, 0 or more; got {wall_s!r}")
    if best_score is None and best_episode is None:
        return
    if not (_is_number(best_score) and _is_whole(best_episode)):
        raise ValueError(f"{path}: best_score and best_episode must be a number and a whole number (both null "
                         f"before the first evaluation); got {best_score!r} and {best_episode!r}")


def _is_whole(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _check_files(checkpoint: Path, files: Any) -> None:
    if not isinstance(files, dict) or not all(isinstance(v, str) for v in files.values()):
        raise ValueError(f"{checkpoint / 'state.json'}: 'files' must map each file to its SHA-256")
    allowed = {TENSORS_FILE, BUFFER_FILE, *(f"best/{name}" for name in BEST_FILES)}
    present = {str(path.relative_to(checkpoint)) for path in checkpoint.rglob("*") if not path.is_dir()}
    present.discard("state.json")
    for name in sorted(present):
        if name not in allowed:
            raise ValueError(f"{checkpoint / name}: not a file autoscoop writes in a checkpoint (it is not opened: "
                             "resume loads no pickle); remove it, or start the run again")
        if name not in files:
            raise ValueError(f"{checkpoint / name}: not listed in {checkpoint / 'state.json'}; remove it, or start "
                             "the run again")
    for name, digest in sorted(files.items()):
        if name not in allowed or name not in present:
            raise ValueError(f"{checkpoint / name}: listed in state.json but missing or not expected there")
        if sha256_of(checkpoint / name) != digest:
            raise ValueError(f"{checkpoint / name}: does not match the SHA-256 recorded in state.json")
    if TENSORS_FILE not in files:
        raise ValueError(f"{checkpoint / TENSORS_FILE}: missing")
    subfolders = sorted(p.name for p in checkpoint.iterdir() if p.is_dir() and p.name != "best")
    if subfolders:
        raise ValueError(f"{checkpoint / subfolders[0]}: not a folder autoscoop writes in a checkpoint")


def load_checkpoint(model: Any, checkpoint: Path, state: dict[str, Any]) -> None:
    """Put the tensors, counters, noise and replay buffer of ``checkpoint/`` into ``model`` (built afresh from
    the run's settings; ``state`` from :func:`read_checkpoint_state`). Reads safetensors, ``.npz`` without
    pickle and JSON only.

    Raises:
        ValueError: the files do not fit the model (the message names the file).
    """
    load_model_state(model, checkpoint, state["model"])


def restore_to_checkpoint(run_dir: Path, checkpoint: Path, state: dict[str, Any]) -> None:
    """Make ``run_dir``'s files what they were at ``checkpoint``: the CSVs cut to its rows, the best policy its
    copy, the evaluated actors and ``last.*`` of later episodes gone (they are made again)."""
    kept = {path: _first_rows(path, rows) for path, rows in ((run_dir / "episodes.csv", state["episodes_done"]),
                                                            (run_dir / "evaluations.csv", state["evaluations_done"]))}
    for path, text in kept.items():  # after both are checked
        if text is not None:
            write_text_atomically(path, text)
    for name in BEST_FILES:
        kept = checkpoint / "best" / name
        if kept.is_file():
            tmp = run_dir / (name + ".tmp")
            shutil.copyfile(kept, tmp)
            os.replace(tmp, run_dir / name)
        else:
            (run_dir / name).unlink(missing_ok=True)
    drop_evaluated_after(run_dir / "evaluated", state["episodes_done"])
    for name in ("last.safetensors", "last.json", "learning_curve.png"):
        (run_dir / name).unlink(missing_ok=True)


def clear_run_outputs(run_dir: Path) -> None:
    """Remove what training wrote into ``run_dir`` (:data:`RUN_OUTPUTS`), keeping its settings and ``run.json``."""
    for name in RUN_OUTPUTS:
        path = run_dir / name
        if path.is_dir():
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)


def remove_checkpoints(run_dir: Path) -> None:
    """Remove every checkpoint folder (:data:`CHECKPOINT_DIRS`) of a finished run."""
    for name in CHECKPOINT_DIRS:
        shutil.rmtree(run_dir / name, ignore_errors=True)


def _first_rows(path: Path, rows: int) -> str | None:
    """The header and first ``rows`` rows of CSV ``path`` (what the checkpoint had seen); ``None`` where the
    file and the rows are both absent.

    Raises:
        ValueError: the file holds fewer complete rows than that (it was cut or replaced since).
    """
    if not path.exists():
        if rows:
            raise ValueError(f"{path}: missing, the checkpoint saw {rows} rows of it; cannot resume consistently")
        return None
    lines = path.read_text().splitlines(keepends=True)
    complete = [line for line in lines[1:1 + rows] if line.endswith("\n")]
    if len(complete) < rows:
        raise ValueError(f"{path}: holds {len(complete)} complete rows, the checkpoint saw {rows}; "
                         "cannot resume consistently")
    return "".join(lines[:1 + rows])


def drop_evaluated_after(folder: Path, episodes: int) -> None:
    """Remove the evaluated actors (``episode_NNNNN.*``) of episodes after ``episodes`` (they are evaluated again)."""
    if not folder.is_dir():
        return
    for path in folder.glob("episode_*.*"):
        number = path.stem.removeprefix("episode_")
        if number.isdigit() and int(number) > episodes:
            path.unlink()


SELECTION_FILE = "selection.json"
"""the validation of a run's best snapshots and which one it kept (a recipe with a ``selection`` section)."""


def snapshot_candidates(run_dir: Path, count: int, after_episode: int = 0) -> list[tuple[int, float, Path]]:
    """The ``count`` best evaluated snapshots of a run after ``after_episode``: (episode, periodic score, actor
    file), highest ``delivered_fill`` in ``evaluations.csv`` first (the later episode first on a tie), only
    those whose actor file ``evaluated/episode_NNNNN.safetensors`` exists."""
    path = run_dir / "evaluations.csv"
    if not path.is_file():
        return []
    with path.open(newline="") as handle:
        rows = [(int(row["episode"]), float(row["delivered_fill"])) for row in csv.DictReader(handle)]
    rows = [(episode, score) for episode, score in rows if episode > after_episode]
    rows.sort(key=lambda item: (-item[1], -item[0]))
    found = []
    for episode, score in rows:
        actor = run_dir / "evaluated" / f"episode_{episode:05d}.safetensors"
        if actor.is_file() and actor.with_suffix(".json").is_file():
            found.append((episode, score, actor))
        if len(found) == count:
            break
    return found


def keep_snapshot(run_dir: Path, episode: int, record: dict[str, Any]) -> None:
    """Make snapshot ``episode`` the run's policy: copy its actor and metadata over ``policy.safetensors`` and
    ``policy.json``, write ``record`` to ``selection.json`` and the episode to ``run.json``
    (``selected_episode``). ``policy.zip`` stays the best periodic evaluation's full model (fine-tuning's start).
    The critic file, the last actor's, names the kept actor in its sidecar (``kept_actor_sha256``)."""
    actor = run_dir / "evaluated" / f"episode_{episode:05d}.safetensors"
    for source, target in ((actor, run_dir / "policy.safetensors"), (actor.with_suffix(".json"), run_dir / "policy.json")):
        tmp = target.with_name(target.name + ".tmp")
        shutil.copyfile(source, tmp)
        os.replace(tmp, target)
    if (run_dir / CRITIC_FILE).is_file():
        name_kept_actor(run_dir / CRITIC_FILE, sha256_of(actor))
    info = read_run_json(run_dir)
    info["selected_episode"] = episode
    write_run_json(run_dir, info)
    _write_json_atomically(run_dir / SELECTION_FILE, record)


def write_run_json(run_dir: Path, info: dict[str, Any]) -> None:
    """Replace ``run.json`` atomically (a crash leaves the old one or the new one, never half of one); it records
    the machine of the run (name and machine.yaml's sha256) unless ``info`` already does."""
    write_json_atomically(run_dir / "run.json", {**machine_record(kinematics.MACHINE), **info})


def refuse_run_of_other_machine(run_dir: Path, info: dict[str, Any]) -> None:
    """Refuse to continue or start from a run trained on another machine than this process's.

    Raises:
        MachineError: naming the run's machine and this one's.
    """
    refuse_other_machine(info, kinematics.MACHINE, f"run {run_dir}")


def read_run_yaml(run_dir: Path, name: str) -> Any:
    """A YAML file of a run directory (``config.yaml``, ``hyperparams.yaml``), read within bounds
    (:func:`autoscoop.core.safe_files.read_yaml`).

    Raises:
        ValueError: missing, too large or not accepted YAML (the message names the file).
    """
    return read_yaml(Path(run_dir) / name, "run file")


def read_run_json(run_dir: Path) -> dict[str, Any]:
    """A run directory's ``run.json``.

    Raises:
        ValueError: ``run_dir`` has none, or it is too large or not a JSON object (the message names it).
    """
    info_path = run_dir / "run.json"
    if not info_path.exists():
        raise ValueError(f"{run_dir} is not a run directory (no run.json)")
    info = read_json(info_path, "run file")
    if not isinstance(info, dict):
        raise ValueError(f"run file {info_path}: expected a JSON object, got a {type(info).__name__}")
    return info


LOCK_FILE = ".lock"
"""the lock a process writing a run directory holds (``filelock``; the OS frees it if the process dies)."""
HOLDER_FILE = "lock.json"
"""who holds :data:`LOCK_FILE`: PID, host and start time, for the message a second process gets."""


def _holder_text(run_dir: Path) -> str:
    try:
        holder = read_json(run_dir / HOLDER_FILE, "lock holder", 4096)
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
        write_json_atomically(holder, {"pid": os.getpid(), "host": socket.gethostname(),
                                       "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}, indent=None)
        yield
    finally:
        holder.unlink(missing_ok=True)
        lock.release()


def init_source(run_dir: Path, algo: str, trust: bool) -> Path:
    """The file of a finished run to fine-tune from, checked now (before a new run directory is made).

    Without ``trust`` that is the run's safe actor (``policy.safetensors``: the actor starts from it, the
    critic from fresh weights); with ``trust``, its ``policy.zip`` (the whole model, pickle inside). Nothing in
    the run directory vouches for its own zip: whoever can write the zip can write ``run.json``.

    Raises:
        ValueError: not a run directory, another algorithm, a safe actor that does not load, or only a zip
            and no ``trust``.
    """
    run_dir = Path(run_dir)
    if not (run_dir / "run.json").is_file():
        raise ValueError(f"--init {run_dir}: not a training run directory (needs run.json)")
    source_algo = read_run_json(run_dir).get("algo")
    if source_algo != algo:
        raise ValueError(f"--init {run_dir}: that run trained {quote(source_algo)}, this one trains {algo!r}")
    zip_path, actor_path = run_dir / "policy.zip", run_dir / "policy.safetensors"
    if trust and zip_path.is_file():
        return zip_path
    if actor_path.is_file():
        load_actor(actor_path)  # its format, hash and shapes, now
        return actor_path
    if zip_path.is_file():
        refuse_untrusted_zip(zip_path, trust, "--init")
    raise ValueError(f"--init {run_dir}: holds neither policy.safetensors nor policy.zip")


def load_init_weights(model: Any, path: Path, sha256: str, trust: bool) -> None:
    """Copy the policy a run starts from (:func:`init_source`) into ``model``: a safe actor into its actor, a
    zip's networks (actor, critic and their targets) only with ``trust``.

    Raises:
        ValueError: the file changed since the run recorded it, does not fit, or is a zip without ``trust``.
    """
    if not path.is_file() or sha256_of(path) != sha256:
        raise ValueError(f"{path} is missing or changed since this run started from it (SHA-256); refusing to load it")
    if path.suffix == ".safetensors":
        actor, _ = load_actor(path)
        actor_into_sb3(actor, model)
        return
    refuse_untrusted_zip(path, trust, "--init")
    source = type(model).load(path, device="cpu")
    model.policy.load_state_dict(source.policy.state_dict())
