"""Policy files for deployment: the actor's weights in safetensors plus a JSON sidecar, never pickle.

``NAME.safetensors`` holds the tensors of :class:`autoscoop.agents.networks.PaperActor` (its input
normalisation included); ``NAME.json`` holds the format version, architecture, the algorithm and
run it came from, and the SHA-256 of the weights file, checked on every load.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors import SafetensorError, safe_open
from safetensors.torch import load_file, save_file

from autoscoop.agents.networks import PaperActor
from autoscoop.core import kinematics
from autoscoop.core.machine import machine_record, refuse_other_machine
from autoscoop.core.safe_files import UnsafeInputError, atomic_output, quote, read_json, write_json_atomically
from autoscoop.core.state import (
    ActorInputHistory,
    checked_history_steps,
    history_steps_for_input,
    recorded_state_frame,
)

FORMAT = "autoscoop-actor/1"


class PolicyFileError(ValueError):
    """A policy file that is missing, malformed, or does not match its recorded hash."""


def sha256_of(path: str | Path) -> str:
    """Hex SHA-256 of a file."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for chunk in iter(lambda: handle.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


MAX_WEIGHTS_BYTES = 64 << 20
"""cap of an actor's ``.safetensors`` file, bytes (the paper's actor is about 60 KB)."""
MAX_SIDECAR_BYTES = 64 << 10
"""cap of an actor's ``.json`` sidecar, bytes."""
MAX_LAYERS, MAX_WIDTH = 16, 4096
"""the most hidden layers, and units per layer, a sidecar may declare."""


def save_actor(actor: PaperActor, path: str | Path, metadata: dict[str, Any] | None = None) -> Path:
    """Write ``path`` (.safetensors) and its ``.json`` sidecar, each atomically; return the weights path."""
    path = Path(path).with_suffix(".safetensors")
    tensors = {name: tensor.detach().cpu().contiguous() for name, tensor in actor.state_dict().items()}
    with atomic_output(path) as tmp:
        save_file(tensors, str(tmp))
    sidecar = {"format": FORMAT, "layers": list(actor.layers), "output": "tanh", "sha256": sha256_of(path),
               **machine_record(kinematics.MACHINE), **(metadata or {})}
    if actor.history_steps > 1:  # files of the state alone stay as they were
        sidecar["history_steps"] = actor.history_steps
    write_json_atomically(path.with_suffix(".json"), sidecar)
    return path


def load_actor(path: str | Path) -> tuple[PaperActor, dict[str, Any]]:
    """Read an actor written by :func:`save_actor`, checking, before anything is allocated, the files' sizes,
    the sidecar's format and hash, and its layers against the weights file's own header.

    Raises:
        PolicyFileError: when a file is missing, too large or malformed, the format is unknown, the hash
            differs or the weights do not fit the recorded architecture.
    """
    path = Path(path).with_suffix(".safetensors")
    sidecar_path = path.with_suffix(".json")
    if not path.is_file() or not sidecar_path.is_file():
        raise PolicyFileError(f"policy file {path} needs both {path.name} and {sidecar_path.name}")
    try:
        meta = read_json(sidecar_path, "policy sidecar", MAX_SIDECAR_BYTES)
    except UnsafeInputError as error:
        raise PolicyFileError(str(error)) from None
    if not isinstance(meta, dict):
        raise PolicyFileError(f"{sidecar_path}: expected a JSON object with format, layers and sha256, "
                              f"got a {type(meta).__name__}")
    if meta.get("format") != FORMAT:
        raise PolicyFileError(f"{sidecar_path}: format {quote(meta.get('format'))}, expected {FORMAT!r}")
    if path.stat().st_size > MAX_WEIGHTS_BYTES:
        raise PolicyFileError(f"{path}: larger than {MAX_WEIGHTS_BYTES} bytes; not an actor autoscoop writes")
    actual = sha256_of(path)
    if actual != meta.get("sha256"):
        raise PolicyFileError(f"{path}: SHA-256 {actual} does not match the recorded {quote(meta.get('sha256'))}")
    layers = meta.get("layers")
    if not (isinstance(layers, list) and 0 < len(layers) <= MAX_LAYERS
            and all(isinstance(n, int) and not isinstance(n, bool) and 0 < n <= MAX_WIDTH for n in layers)):
        raise PolicyFileError(f"{sidecar_path}: 'layers' must be a list of 1 to {MAX_LAYERS} whole numbers in "
                              f"[1, {MAX_WIDTH}] (hidden layer widths, e.g. [100, 80, 60]); got {quote(layers)}")
    try:
        history = checked_history_steps(meta.get("history_steps", 1), str(sidecar_path))
    except ValueError as error:
        raise PolicyFileError(str(error)) from None
    _check_header(path, layers, history)
    actor = PaperActor(layers=layers, history_steps=history)
    try:
        tensors = load_file(str(path))
        actor.load_state_dict(tensors)
    except (RuntimeError, KeyError, SafetensorError) as error:
        raise PolicyFileError(f"{path}: weights do not fit the recorded architecture ({quote(str(error))})") from None
    broken = sorted(name for name, tensor in tensors.items() if not torch.isfinite(tensor).all())
    if broken:
        raise PolicyFileError(f"{path}: tensor {broken[0]} holds NaN or infinite values; the actor would command NaN")
    actor.eval()
    return actor, meta


def _check_header(path: Path, layers: list[int], history_steps: int = 1) -> None:
    """Compare the tensors the weights file declares (names, float32, shapes) with those of an actor of
    ``layers`` reading ``history_steps`` states, built on torch's ``meta`` device (no memory)."""
    try:
        with safe_open(str(path), framework="pt") as weights:
            found = {name: (weights.get_slice(name).get_dtype(), tuple(weights.get_slice(name).get_shape()))
                     for name in weights.keys()}
    except (SafetensorError, OSError) as error:
        raise PolicyFileError(f"{path}: not a readable safetensors file ({quote(str(error))})") from None
    with torch.device("meta"):
        expected = {name: ("F32", tuple(tensor.shape)) for name, tensor in PaperActor(layers=layers, history_steps=history_steps)
                    .state_dict().items()}
    if found != expected:
        differ = sorted(name for name in found.keys() | expected.keys() if found.get(name) != expected.get(name))
        shown = ", ".join(f"{name} {found.get(name, 'missing')} (expected {expected.get(name, 'none')})"
                          for name in differ[:3])
        raise PolicyFileError(f"{path}: weights do not fit the recorded architecture {layers}: {quote(shown, 400)}")


class ActorPolicy:
    """A :class:`autoscoop.core.policy.Policy` that runs a saved actor with torch.

    Args:
        path: the ``.safetensors`` file (its ``.json`` sidecar beside it).
        name: label used in reports.
    """

    def __init__(self, path: str | Path, name: str | None = None) -> None:
        self.actor, self.metadata = load_actor(path)
        self.name = name or Path(path).stem
        refuse_other_machine(self.metadata, kinematics.MACHINE, str(path))
        try:
            self.state_frame = recorded_state_frame(self.metadata, path)
        except ValueError as error:
            raise PolicyFileError(str(error)) from None

        self.history = ActorInputHistory(self.actor.history_steps)

    def reset(self) -> None:
        """Forget the episode's history (an actor of the state alone keeps none)."""
        self.history.reset()

    def act(self, observation: np.ndarray) -> np.ndarray:
        """The action for this 12-number state (the actor's input built by :class:`ActorInputHistory`)."""
        with torch.no_grad():
            actor_input = torch.as_tensor(self.history.observe(observation)).reshape(1, -1)
            action = self.actor(actor_input)[0].numpy()
        self.history.acted(action)
        return action


def actor_from_sb3(model: Any, target: bool = False) -> PaperActor:
    """Copy the deterministic actor of an SB3 model trained with the paper's policies into a PaperActor.

    With ``target``, DDPG's and TD3's target actor instead: the Polyak average of the actor's weights that
    the critic's targets use (each gradient step moves it ``tau`` of the way to the actor).

    Raises:
        PolicyFileError: the model has no such actor (PPO; SAC has no target actor).
    """
    from autoscoop.agents.sb3_policies import PaperActorSB3  # noqa: PLC0415

    sb3_actor = getattr(model.policy, "actor", None)  # PPO's ActorCriticPolicy has none
    if target:
        sb3_actor = getattr(model.policy, "actor_target", None)
        if not isinstance(sb3_actor, PaperActorSB3):
            raise PolicyFileError(f"a {type(model).__name__} model has no target actor of the paper's policy")
    if isinstance(sb3_actor, PaperActorSB3):  # DDPG, TD3: mu = Sequential(body, head, tanh)
        body, head = sb3_actor.mu[0], sb3_actor.mu[1]
    elif hasattr(sb3_actor, "latent_pi") and hasattr(sb3_actor, "mu"):  # SAC with the paper's body
        body, head = sb3_actor.latent_pi, sb3_actor.mu
    else:
        raise PolicyFileError(f"cannot export the actor of {type(model).__name__} to the safe format")
    linear = [m for m in body if isinstance(m, torch.nn.Linear)]
    layers = [m.out_features for m in linear]
    actor = PaperActor(layers=layers, history_steps=history_steps_for_input(linear[0].in_features))
    actor.body.load_state_dict(body.state_dict())
    actor.head.load_state_dict(head.state_dict())
    return actor.eval()


def actor_into_sb3(actor: PaperActor, model: Any) -> None:
    """Copy ``actor``'s weights into an SB3 model built with the paper's policy (DDPG, TD3: the actor and its
    target; SAC: the mean of its actor); the inverse of :func:`actor_from_sb3`. The critic is left as it is.

    Raises:
        PolicyFileError: the model has no such actor, or one of other layer widths.
    """
    from autoscoop.agents.sb3_policies import PaperActorSB3  # noqa: PLC0415

    sb3_actor = getattr(model.policy, "actor", None)
    if isinstance(sb3_actor, PaperActorSB3):
        body, head = sb3_actor.mu[0], sb3_actor.mu[1]
    elif hasattr(sb3_actor, "latent_pi") and hasattr(sb3_actor, "mu"):
        body, head = sb3_actor.latent_pi, sb3_actor.mu
    else:
        raise PolicyFileError(f"a {type(model).__name__} model has no paper actor to start from a safe actor file")
    try:
        body.load_state_dict(actor.body.state_dict())
        head.load_state_dict(actor.head.state_dict())
    except RuntimeError as error:
        raise PolicyFileError(f"the actor's layers {list(actor.layers)} do not fit this run's networks "
                              f"({quote(str(error))})") from None
    target = getattr(model.policy, "actor_target", None)
    if target is not None:
        target.load_state_dict(sb3_actor.state_dict())
