"""The paper's networks in plain torch (Fig. 6): used by the SB3 policy, the safe policy files and ONNX export.

Actor: state -> 100 -> 80 -> 60 -> 3, each hidden layer fully connected, then layer normalisation,
then ReLU; tanh on the output. Critic: state -> 100 (LayerNorm, ReLU); the action joins there;
-> 80 -> 60 (each LayerNorm, ReLU) -> Q. Both start with a fixed normalisation of the state
(:data:`autoscoop.core.state.STATE_CENTRE`, :data:`autoscoop.core.state.STATE_SCALE`) stored as buffers, so
a saved actor carries its input scaling.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from autoscoop.core.state import ACTION_SIZE, actor_input_normalization, actor_input_size

PAPER_LAYERS = (100, 80, 60)


class StateNormalizer(nn.Module):
    """(state - centre) / scale with fixed constants; with ``history_steps`` > 1 the actor's input of that
    many states and commands (:func:`autoscoop.core.state.actor_input_normalization`)."""

    def __init__(self, history_steps: int = 1) -> None:
        super().__init__()
        centre, scale = actor_input_normalization(history_steps)
        self.register_buffer("centre", torch.as_tensor(centre))
        self.register_buffer("scale", torch.as_tensor(scale))

    def forward(self, state: torch.Tensor) -> torch.Tensor:
        return (state - self.centre) / self.scale


def _layer(n_in: int, n_out: int) -> list[nn.Module]:
    return [nn.Linear(n_in, n_out), nn.LayerNorm(n_out), nn.ReLU()]


def paper_mlp(n_in: int, layers: Sequence[int]) -> nn.Sequential:
    """Fully connected layers, each followed by layer normalisation and ReLU."""
    modules: list[nn.Module] = []
    for width in layers:
        modules += _layer(n_in, width)
        n_in = width
    return nn.Sequential(*modules)


class PaperActor(nn.Module):
    """mu(s): the deterministic policy, state (12) -> action in [-1, 1] (3); the input is a raw state, or with
    ``history_steps`` k > 1 the raw input of :class:`autoscoop.core.state.ActorInputHistory`."""

    def __init__(self, layers: Sequence[int] = PAPER_LAYERS, normalize: bool = True, history_steps: int = 1) -> None:
        super().__init__()
        self.layers = tuple(layers)
        self.history_steps = int(history_steps)
        self.normalizer = StateNormalizer(history_steps) if normalize else nn.Identity()
        self.body = paper_mlp(actor_input_size(history_steps), self.layers)
        self.head = nn.Linear(self.layers[-1], ACTION_SIZE)

    def forward(self, state: torch.Tensor) -> torch.Tensor:
        return torch.tanh(self.head(self.body(self.normalizer(state))))


class PaperQNetwork(nn.Module):
    """Q(s, a) with the action merged after the first layer."""

    def __init__(self, features_dim: int, action_dim: int, layers: Sequence[int] = PAPER_LAYERS) -> None:
        super().__init__()
        self.first = nn.Sequential(*_layer(features_dim, layers[0]))
        self.rest = paper_mlp(layers[0] + action_dim, layers[1:])
        self.out = nn.Linear(layers[-1], 1)

    def forward(self, features: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return self.out(self.rest(torch.cat([self.first(features), action], dim=1)))
