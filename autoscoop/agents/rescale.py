"""Move a trained controller to a loader of another size: fold a Froude scaling of its input into its first layer.

A loader S times another's size (lengths x S, masses x S^3, the same control period) meets the same scoop at
states that differ by fixed factors (:func:`autoscoop.core.state.froude_input_factors`). The networks normalise
their input with fixed constants and then apply a linear layer, so answering an input ``x * f`` as the original
answered ``x`` changes that layer alone:

    W' = W / f,    b' = b + W (c (1 - f) / (f s))

with ``c`` and ``s`` the normalisation's centre and scale (the input is normalised as ``(x - c) / s``). The actor
file keeps its format (the ONNX export, the ROS node and the rollout loop are unchanged); a critic's first layer
is folded over the actor-input part of its features, its privileged numbers left as they are.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from autoscoop.agents.networks import PaperActor
from autoscoop.core.state import actor_input_normalization, froude_input_factors


def fold_input_factors(linear: torch.nn.Linear, factors: np.ndarray, centre: np.ndarray, scale: np.ndarray) -> None:
    """Change ``linear``, the layer after the normalisation ``(x - centre) / scale``, in place so that it answers
    ``x * factors`` as it answered ``x``, on its first ``len(factors)`` inputs (the rest untouched)."""
    f = np.asarray(factors, dtype=np.float64)
    c, s = np.asarray(centre, dtype=np.float64), np.asarray(scale, dtype=np.float64)
    n = f.size
    with torch.no_grad():
        weight = linear.weight.detach().double()
        shift = weight[:, :n] @ torch.as_tensor(c * (1.0 - f) / (f * s))
        linear.weight[:, :n] = (weight[:, :n] / torch.as_tensor(f)).to(linear.weight.dtype)
        linear.bias += shift.to(linear.bias.dtype)


def _first_linear(module: torch.nn.Module) -> torch.nn.Linear:
    return next(m for m in module.modules() if isinstance(m, torch.nn.Linear))


def rescaled_actor(actor: PaperActor, length_scale: float) -> PaperActor:
    """``actor`` for a loader ``length_scale`` times the size of the one it was trained on (modified in place and returned)."""
    centre, scale = actor_input_normalization(actor.history_steps)
    fold_input_factors(_first_linear(actor.body), froude_input_factors(length_scale, actor.history_steps), centre, scale)
    return actor


def rescale_critics(model: Any, length_scale: float, history_steps: int) -> None:
    """Fold the same scaling into each critic (and target critic) of an SB3 model built with the paper's critic."""
    centre, scale = actor_input_normalization(history_steps)
    factors = froude_input_factors(length_scale, history_steps)
    for critic in (model.policy.critic, getattr(model.policy, "critic_target", None)):
        for q_net in getattr(critic, "q_networks", []):
            fold_input_factors(_first_linear(q_net.first), factors, centre, scale)
