"""A model's training state without pickle: tensors in safetensors, the replay buffer in ``.npz``, the rest JSON.

Stable-Baselines3's ``model.save`` and ``save_replay_buffer`` pickle, and reading them back runs
``torch.load`` and ``pickle.load``, which can run code. A checkpoint keeps instead:

* ``tensors.safetensors``: every state dict SB3 saves (the policy's networks and their targets, each
  optimizer's moments and step counts) and SAC's entropy coefficient, flattened;
* ``replay_buffer.npz``: the replay buffer's filled rows with ``pos`` and ``full`` (read with ``allow_pickle=False``);
* a JSON-able dict (:func:`save_model_state` returns it; the checkpoint's ``state.json`` holds it): how the
  tensors nest (the optimizers' hyperparameters included), SB3's counters, the exploration noise's scale and state.

:func:`load_model_state` fills a model built afresh from the run's settings (same algorithm, networks and
buffer size): nothing in these files picks a class or a function, so nothing in them can run.
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors import SafetensorError
from safetensors.torch import load_file, save_file

TENSORS_FILE = "tensors.safetensors"
"""the model's tensors, flattened (keys like ``policy/actor.mu.0.weight``, ``actor.optimizer/state/0/exp_avg``)."""
BUFFER_FILE = "replay_buffer.npz"
"""the replay buffer's filled rows, ``pos`` and ``full`` (off-policy algorithms only)."""
BUFFER_ARRAYS = ("observations", "next_observations", "actions", "rewards", "dones", "timeouts")
"""the arrays of SB3's ``ReplayBuffer`` that hold transitions (``next_observations`` is ``None`` when memory is optimised)."""
SB3_COUNTERS = {"num_timesteps": int, "_episode_num": int, "_n_updates": int, "_current_progress_remaining": float}
"""SB3's training counters, by name and type: steps taken, episodes, gradient updates, learning-rate progress
(1 at the start, 0 at the end). Only ``num_timesteps`` is public; the others have no public way in, so they
are read and written by name here and nowhere else."""
EXTRA_TENSORS = ("log_ent_coef", "ent_coef_tensor")
"""tensors SB3 keeps outside the state dicts (SAC's entropy coefficient, learned or fixed)."""
STATE_KEYS = ("counters", "state_dicts", "extra_tensors", "noise", "replay_buffer")
"""the keys of the dict :func:`save_model_state` returns."""


def save_model_state(model: Any, folder: Path) -> dict[str, Any]:
    """Write ``folder/tensors.safetensors`` (and ``replay_buffer.npz`` for off-policy models); return the rest
    as a JSON-able dict for :func:`load_model_state`."""
    tensors: dict[str, torch.Tensor] = {}
    skeleton = {name: _encode(state, name, tensors) for name, state in model.get_parameters().items()}
    extras = {name: _encode(getattr(model, name), f"extra/{name}", tensors)
              for name in EXTRA_TENSORS if isinstance(getattr(model, name, None), torch.Tensor)}
    save_file(tensors, str(folder / TENSORS_FILE))
    buffer = getattr(model, "replay_buffer", None)
    if buffer is not None:
        save_replay_buffer(buffer, folder / BUFFER_FILE)
    return {"counters": {name: kind(getattr(model, name)) for name, kind in SB3_COUNTERS.items()},
            "state_dicts": skeleton, "extra_tensors": extras, "noise": noise_state(getattr(model, "action_noise", None)),
            "replay_buffer": BUFFER_FILE if buffer is not None else None}


def load_model_state(model: Any, folder: Path, state: dict[str, Any]) -> None:
    """Put what :func:`save_model_state` wrote into ``model`` (built from the same run settings).

    Raises:
        ValueError: a file is missing or malformed, or does not fit the model (the message names it).
    """
    missing = [key for key in STATE_KEYS if key not in state] if isinstance(state, dict) else list(STATE_KEYS)
    if missing:
        raise ValueError(f"{folder}: the checkpoint's model state lacks {', '.join(missing)}")
    path = folder / TENSORS_FILE
    try:
        tensors = load_file(str(path))
    except (OSError, SafetensorError) as error:
        raise ValueError(f"{path}: not a safetensors file ({error})") from None
    try:
        params = {name: _decode(node, tensors) for name, node in state["state_dicts"].items()}
        extras = {name: _decode(node, tensors) for name, node in state["extra_tensors"].items()}
        expected = set(model.get_parameters())
        if set(params) != expected:
            raise ValueError(f"holds state dicts {sorted(params)}, the model has {sorted(expected)}")
        model.set_parameters(params, exact_match=True, device="cpu")
        for name, value in extras.items():
            _copy_extra_tensor(model, name, value)
    except (KeyError, TypeError, ValueError, RuntimeError, AttributeError) as error:
        raise ValueError(f"{path}: does not fit this run's model ({error})") from None
    _set_counters(model, state["counters"], folder)
    set_noise_state(getattr(model, "action_noise", None), state["noise"], folder)
    buffer = getattr(model, "replay_buffer", None)
    if (buffer is None) != (state["replay_buffer"] is None):
        raise ValueError(f"{folder}: the checkpoint's replay buffer ({state['replay_buffer']}) does not fit this "
                         f"run's algorithm ({'no' if buffer is None else 'a'} replay buffer)")
    if buffer is not None:
        load_replay_buffer(buffer, folder / BUFFER_FILE)


def _encode(value: Any, key: str, tensors: dict[str, torch.Tensor]) -> dict[str, Any]:
    """``value`` (a state dict, or part of one) as JSON, its tensors moved to ``tensors`` under ``key/...``."""
    if isinstance(value, torch.Tensor):
        if key in tensors:
            raise ValueError(f"two tensors would be stored as {key!r}")
        tensors[key] = value.detach().cpu().clone().contiguous()  # clone: safetensors refuses shared storage
        return {"tensor": key}
    if isinstance(value, dict):
        if not all(isinstance(k, (str, int)) and not isinstance(k, bool) for k in value):
            raise TypeError(f"{key}: keys must be strings or integers, got {sorted(map(repr, value))}")
        return {"dict": [[k, _encode(v, f"{key}/{k}", tensors)] for k, v in value.items()]}
    if isinstance(value, (list, tuple)):
        return {type(value).__name__: [_encode(v, f"{key}/{i}", tensors) for i, v in enumerate(value)]}
    if value is None or isinstance(value, (bool, int, float, str)):
        return {"value": value}
    raise TypeError(f"{key}: a {type(value).__name__} cannot be kept without pickle")


def _decode(node: Any, tensors: dict[str, torch.Tensor]) -> Any:
    """The inverse of :func:`_encode` (``ValueError`` on anything it would not have written)."""
    if not isinstance(node, dict) or len(node) != 1:
        raise ValueError(f"malformed entry {node!r:.80}")
    (kind, body), = node.items()
    if kind == "tensor":
        if body not in tensors:
            raise ValueError(f"no tensor {body!r}")
        return tensors[body]
    if kind == "dict" and isinstance(body, list) and all(isinstance(pair, list) and len(pair) == 2 for pair in body):
        if not all(isinstance(k, (str, int)) and not isinstance(k, bool) for k, _ in body):
            raise ValueError(f"malformed keys in {node!r:.80}")
        return {k: _decode(v, tensors) for k, v in body}
    if kind in ("list", "tuple") and isinstance(body, list):
        items = [_decode(v, tensors) for v in body]
        return items if kind == "list" else tuple(items)
    if kind == "value" and (body is None or isinstance(body, (bool, int, float, str))):
        return body
    raise ValueError(f"malformed entry {node!r:.80}")


def _copy_extra_tensor(model: Any, name: str, value: torch.Tensor) -> None:
    target = getattr(model, name) if name in EXTRA_TENSORS else None
    if not isinstance(target, torch.Tensor) or target.shape != value.shape:
        raise ValueError(f"{name}: the model has no such tensor of shape {tuple(value.shape)}")
    with torch.no_grad():
        target.copy_(value)


def _set_counters(model: Any, counters: Any, folder: Path) -> None:
    if not isinstance(counters, dict) or set(counters) != set(SB3_COUNTERS):
        raise ValueError(f"{folder}: the checkpoint's counters must be {sorted(SB3_COUNTERS)}, got {counters!r:.120}")
    for name, kind in SB3_COUNTERS.items():
        value = counters[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (kind is int and not isinstance(value, int)):
            raise ValueError(f"{folder}: counter {name} must be a {kind.__name__}, got {value!r}")
        setattr(model, name, kind(value))


def _noise_parts(noise: Any) -> list[Any]:
    return [] if noise is None else list(getattr(noise, "noises", [noise]))


def noise_state(noise: Any) -> list[dict[str, Any]]:
    """The exploration noise of each environment: its kind, scale (``sigma``) and, where it has one, its last
    value (Ornstein-Uhlenbeck's ``noise_prev``); ``[]`` without noise."""
    return [{"kind": type(part).__name__, "sigma": np.asarray(part._sigma).tolist(),
             "noise_prev": np.asarray(part.noise_prev).tolist() if hasattr(part, "noise_prev") else None}
            for part in _noise_parts(noise)]


def set_noise_state(noise: Any, state: Any, folder: Path) -> None:
    """Put :func:`noise_state`'s lists back into ``noise`` (made from the same settings).

    Raises:
        ValueError: another kind or number of noises, or arrays of another shape.
    """
    parts = _noise_parts(noise)
    kinds = [type(part).__name__ for part in parts]
    if not isinstance(state, list) or [entry.get("kind") if isinstance(entry, dict) else None
                                       for entry in state] != kinds:
        raise ValueError(f"{folder}: the checkpoint's exploration noise {state!r:.120} does not fit this run's {kinds}")
    for part, entry in zip(parts, state):
        part._sigma = _float_array(entry.get("sigma"), np.shape(part._sigma), folder, "noise sigma")
        if hasattr(part, "noise_prev"):
            part.noise_prev = _float_array(entry.get("noise_prev"), np.shape(part.noise_prev), folder, "noise_prev")


def _float_array(values: Any, shape: tuple[int, ...], folder: Path, what: str) -> np.ndarray:
    try:
        array = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        array = None
    if array is None or array.shape != shape or not np.isfinite(array).all():
        raise ValueError(f"{folder}: the checkpoint's {what} must be {shape} finite numbers, got {values!r:.80}")
    return array


def save_replay_buffer(buffer: Any, path: Path) -> None:
    """Write the filled rows of SB3's ``ReplayBuffer`` (all of them once it is full), ``pos`` and ``full`` to ``path``."""
    rows = buffer.buffer_size if buffer.full else buffer.pos
    arrays = {name: getattr(buffer, name)[:rows] for name in BUFFER_ARRAYS if getattr(buffer, name, None) is not None}
    with open(path, "wb") as handle:
        np.savez(handle, pos=np.int64(buffer.pos), full=np.bool_(buffer.full), **arrays)


def load_replay_buffer(buffer: Any, path: Path) -> None:
    """Fill SB3's ``ReplayBuffer`` (empty, of the run's size) from :func:`save_replay_buffer`'s file.

    Raises:
        ValueError: not such a file (pickled arrays included: they are refused, never loaded), or arrays of
            other names, shapes or types than the buffer's.
    """
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as error:
        raise ValueError(f"{path}: not a replay buffer file autoscoop writes ({error})") from None
    pos, full = arrays.pop("pos", None), arrays.pop("full", None)
    if pos is None or full is None or pos.shape != () or full.shape != () or pos.dtype.kind not in "iu" \
            or full.dtype != np.bool_ or not 0 <= int(pos) < buffer.buffer_size:
        raise ValueError(f"{path}: needs pos (an integer in [0, {buffer.buffer_size})) and full (true or false)")
    rows = buffer.buffer_size if bool(full) else int(pos)
    expected = {name for name in BUFFER_ARRAYS if getattr(buffer, name, None) is not None}
    if set(arrays) != expected:
        raise ValueError(f"{path}: holds {sorted(arrays)}, a replay buffer of this run holds {sorted(expected)}")
    for name, array in arrays.items():
        target = getattr(buffer, name)
        if array.dtype != target.dtype or array.shape != (rows, *target.shape[1:]):
            raise ValueError(f"{path}: {name} is {array.dtype} {array.shape}, expected {target.dtype} "
                             f"{(rows, *target.shape[1:])}")
    for name, array in arrays.items():
        getattr(buffer, name)[:rows] = array
    buffer.pos, buffer.full = int(pos), bool(full)
