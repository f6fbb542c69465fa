"""Critic files: what fine-tuning a policy needs beside its actor, in safetensors plus a JSON sidecar, never pickle.

``NAME.critic.safetensors`` holds the tensors of an off-policy model's critic(s) and their targets (the
paper's critic, its input normalisation included), prefixed ``critic.`` and ``critic_target.``;
``NAME.critic.json`` holds the format version, the number of critics, the size of the observation they read
(the actor's input, then the privileged numbers of an asymmetric critic), the SHA-256 of the weights file and
of the actor they were trained with, and the training settings (the recipe's YAML and the config) that
``autoscoop adapt`` rebuilds the worlds and the reward from. The hashes are checked on every load.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import torch
from safetensors import SafetensorError
from safetensors.torch import load_file, save_file

from autoscoop.agents.policy_files import PolicyFileError, sha256_of
from autoscoop.core.safe_files import UnsafeInputError, atomic_output, quote, read_json, write_json_atomically

FORMAT = "autoscoop-critic/1"
MAX_WEIGHTS_BYTES = 64 << 20
"""cap of a critic's ``.safetensors`` file, bytes (the paper's critic and its target are about 200 KB)."""
MAX_SIDECAR_BYTES = 1 << 20
"""cap of a critic's ``.json`` sidecar, bytes (it carries the recipe and the config)."""
PARTS = ("critic", "critic_target")
"""the networks a critic file holds, as the SB3 policy names them."""


def critic_path_for(actor_path: str | Path) -> Path:
    """Where the critic of the actor ``NAME.safetensors`` lies: ``NAME.critic.safetensors`` beside it."""
    actor_path = Path(actor_path)
    return actor_path.with_name(f"{actor_path.with_suffix('').name}.critic.safetensors")


def _sidecar(path: Path) -> Path:
    return path.with_suffix(".json")


def has_critic(model: Any) -> bool:
    """Whether ``model`` (an SB3 model) has critics of the kind a critic file holds (DDPG, TD3, SAC, TQC)."""
    policy = getattr(model, "policy", None)
    return all(isinstance(getattr(policy, part, None), torch.nn.Module) for part in PARTS)


def save_critic(model: Any, path: str | Path, actor_sha256: str, metadata: dict[str, Any]) -> Path:
    """Write the critic(s) and target critic(s) of ``model`` to ``path`` and its ``.json`` sidecar, atomically.

    Args:
        model: an off-policy SB3 model (:func:`has_critic`).
        path: the ``NAME.critic.safetensors`` file.
        actor_sha256: the SHA-256 of the actor file the critic belongs to.
        metadata: more for the sidecar: ``spec`` (the recipe's YAML as a dict) and ``config`` (the run's config).
    """
    path = Path(path)
    tensors = {f"{part}.{name}": tensor.detach().cpu().clone().contiguous()  # a normaliser's buffers are shared
               for part in PARTS for name, tensor in getattr(model.policy, part).state_dict().items()}
    with atomic_output(path) as tmp:
        save_file(tensors, str(tmp))
    critic = model.policy.critic
    sidecar = {"format": FORMAT, "sha256": sha256_of(path), "actor_sha256": actor_sha256,
               "algo": type(model).__name__.lower(), "n_critics": int(getattr(critic, "n_critics", 1)),
               "observation_size": int(model.observation_space.shape[0]), **metadata}
    write_json_atomically(_sidecar(path), sidecar)
    return path


def name_kept_actor(path: str | Path, kept_actor_sha256: str) -> None:
    """Record in the sidecar of the critic file ``path`` the actor its run kept (``kept_actor_sha256``): a run whose
    selection keeps an earlier snapshot than its last actor pairs that snapshot with the critic of its last actor,
    and the pair travels together (``NAME.safetensors`` beside ``NAME.critic.safetensors``).

    Raises:
        PolicyFileError: as :func:`read_critic_sidecar`.
    """
    meta = read_critic_sidecar(path)
    write_json_atomically(_sidecar(Path(path)), {**meta, "kept_actor_sha256": kept_actor_sha256})


def read_critic_sidecar(path: str | Path) -> dict[str, Any]:
    """The sidecar of a critic file, its format and weights hash checked (no tensor is read).

    Raises:
        PolicyFileError: a file missing, too large or malformed, another format, or a hash that differs.
    """
    path = Path(path)
    sidecar = _sidecar(path)
    if not path.is_file() or not sidecar.is_file():
        raise PolicyFileError(f"critic file {path} needs both {path.name} and {sidecar.name}")
    try:
        meta = read_json(sidecar, "critic sidecar", MAX_SIDECAR_BYTES)
    except UnsafeInputError as error:
        raise PolicyFileError(str(error)) from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        found = meta.get("format") if isinstance(meta, dict) else type(meta).__name__
        raise PolicyFileError(f"{sidecar}: format {quote(found)}, expected {FORMAT!r}")
    if path.stat().st_size > MAX_WEIGHTS_BYTES:
        raise PolicyFileError(f"{path}: larger than {MAX_WEIGHTS_BYTES} bytes; not a critic autoscoop writes")
    if sha256_of(path) != meta.get("sha256"):
        raise PolicyFileError(f"{path}: SHA-256 does not match the recorded {quote(meta.get('sha256'))}")
    for key, kind in (("spec", dict), ("config", dict), ("observation_size", int), ("actor_sha256", str)):
        if not isinstance(meta.get(key), kind):
            raise PolicyFileError(f"{sidecar}: '{key}' must be a {kind.__name__}; got {quote(meta.get(key))}")
    return meta


def critic_into_sb3(path: str | Path, model: Any) -> None:
    """Copy the critic file ``path`` into ``model``'s critic(s) and targets (strict: every tensor must fit).

    Raises:
        PolicyFileError: as :func:`read_critic_sidecar`, a tensor that holds NaN, or networks that do not fit.
    """
    path = Path(path)
    meta = read_critic_sidecar(path)
    if not has_critic(model):
        raise PolicyFileError(f"a {type(model).__name__} model has no critic to start from {path}")
    if int(model.observation_space.shape[0]) != meta["observation_size"]:
        raise PolicyFileError(f"{path}: the critic reads {meta['observation_size']} numbers, this run's observations "
                              f"have {model.observation_space.shape[0]}")
    try:
        tensors = load_file(str(path))
    except (SafetensorError, OSError) as error:
        raise PolicyFileError(f"{path}: not a readable safetensors file ({quote(str(error))})") from None
    broken = sorted(name for name, tensor in tensors.items() if not torch.isfinite(tensor).all())
    if broken:
        raise PolicyFileError(f"{path}: tensor {broken[0]} holds NaN or infinite values")
    for part in PARTS:
        prefix = f"{part}."
        own = {name[len(prefix):]: tensor for name, tensor in tensors.items() if name.startswith(prefix)}
        try:
            getattr(model.policy, part).load_state_dict(own)
        except RuntimeError as error:
            raise PolicyFileError(f"{path}: the {part} does not fit this run's networks "
                                  f"({quote(str(error), 300)})") from None
