"""Policy files for deployment: the actor's weights in safetensors plus a JSON sidecar, never pickle.

``NAME.safetensors`` holds the tensors of :class:`autoscoop.agents.networks.PaperActor` (its input
normalisation included); ``NAME.json`` holds the format version, architecture, the algorithm and
run it came from, and the SHA-256 of the weights file, checked on every load.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors.torch import load_file, save_file

from autoscoop.agents.networks import PaperActor
from autoscoop.core.state import recorded_state_frame

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


def save_actor(actor: PaperActor, path: str | Path, metadata: dict[str, Any] | None = None) -> Path:
    """Write ``path`` (.safetensors) and its ``.json`` sidecar; return the weights path."""
    path = Path(path).with_suffix(".safetensors")
    path.parent.mkdir(parents=True, exist_ok=True)
    tensors = {name: tensor.detach().cpu().contiguous() for name, tensor in actor.state_dict().items()}
    save_file(tensors, str(path))
    sidecar = {"format": FORMAT, "layers": list(actor.layers), "output": "tanh", "sha256": sha256_of(path),
               **(metadata or {})}
    path.with_suffix(".json").write_text(json.dumps(sidecar, indent=2) + "\n")
    return path


def load_actor(path: str | Path) -> tuple[PaperActor, dict[str, Any]]:
    """Read an actor written by :func:`save_actor`, checking format and hash.

    Raises:
        PolicyFileError: when a file is missing, the format is unknown or the hash differs.
    """
    path = Path(path).with_suffix(".safetensors")
    sidecar_path = path.with_suffix(".json")
    if not path.is_file() or not sidecar_path.is_file():
        raise PolicyFileError(f"policy file {path} needs both {path.name} and {sidecar_path.name}")
    try:
        meta = json.loads(sidecar_path.read_text())
    except json.JSONDecodeError as error:
        raise PolicyFileError(f"{sidecar_path}: not valid JSON ({error})") from error
    if not isinstance(meta, dict):
        raise PolicyFileError(f"{sidecar_path}: expected a JSON object with format, layers and sha256, "
                              f"got a {type(meta).__name__}")
    if meta.get("format") != FORMAT:
        raise PolicyFileError(f"{sidecar_path}: format {meta.get('format')!r}, expected {FORMAT!r}")
    actual = sha256_of(path)
    if actual != meta.get("sha256"):
        raise PolicyFileError(f"{path}: SHA-256 {actual} does not match the recorded {meta.get('sha256')}")
    layers = meta.get("layers")
    if not (isinstance(layers, list) and layers and all(isinstance(n, int) and not isinstance(n, bool) and n > 0
                                                        for n in layers)):
        raise PolicyFileError(f"{sidecar_path}: 'layers' must be a non-empty list of positive whole numbers "
                              f"(hidden layer widths, e.g. [100, 80, 60]); got {layers!r}")
    actor = PaperActor(layers=layers)
    try:
        actor.load_state_dict(load_file(str(path)))
    except (RuntimeError, KeyError) as error:
        raise PolicyFileError(f"{path}: weights do not fit the recorded architecture ({error})") from error
    actor.eval()
    return actor, meta


class ActorPolicy:
    """A :class:`autoscoop.core.policy.Policy` that runs a saved actor with torch.

    Args:
        path: the ``.safetensors`` file (its ``.json`` sidecar beside it).
        name: label used in reports.
    """

    def __init__(self, path: str | Path, name: str | None = None) -> None:
        self.actor, self.metadata = load_actor(path)
        self.name = name or Path(path).stem
        try:
            self.state_frame = recorded_state_frame(self.metadata, path)
        except ValueError as error:
            raise PolicyFileError(str(error)) from None

    def reset(self) -> None:
        """The actor is stateless."""

    def act(self, observation: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            state = torch.as_tensor(np.asarray(observation, dtype=np.float32)).reshape(1, -1)
            return self.actor(state)[0].numpy()


def actor_from_sb3(model: Any) -> PaperActor:
    """Copy the deterministic actor of an SB3 model trained with the paper's policies into a PaperActor."""
    from autoscoop.agents.sb3_policies import PaperActorSB3  # noqa: PLC0415

    sb3_actor = getattr(model.policy, "actor", None)  # PPO's ActorCriticPolicy has none
    if isinstance(sb3_actor, PaperActorSB3):  # DDPG, TD3: mu = Sequential(body, head, tanh)
        body, head = sb3_actor.mu[0], sb3_actor.mu[1]
    elif hasattr(sb3_actor, "latent_pi") and hasattr(sb3_actor, "mu"):  # SAC with the paper's body
        body, head = sb3_actor.latent_pi, sb3_actor.mu
    else:
        raise PolicyFileError(f"cannot export the actor of {type(model).__name__} to the safe format")
    layers = [m.out_features for m in body if isinstance(m, torch.nn.Linear)]
    actor = PaperActor(layers=layers)
    actor.body.load_state_dict(body.state_dict())
    actor.head.load_state_dict(head.state_dict())
    return actor.eval()
