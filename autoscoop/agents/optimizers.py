"""Optimisers for fine-tuning a trained policy."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import torch


class HeldAdam(torch.optim.Adam):
    """Adam that makes no update for its first ``hold_steps`` steps and then scales each step by ``lr_scale``.

    Fine-tuning a trained actor beside a critic that must first learn the new world: the actor holds still
    while the critic settles, then moves at a fraction of the critic's learning rate. Stable-Baselines3 sets
    ``lr`` on every step from its schedule, so the scale lives apart from it. ``hold_steps``, ``lr_scale`` and
    the steps taken are kept in each parameter group, so they travel with ``state_dict()`` (a resumed run
    holds and scales as the interrupted one would have).
    """

    def __init__(self, params: Iterable[Any], lr: float = 1e-3, hold_steps: int = 0, lr_scale: float = 1.0,
                 **kwargs: Any) -> None:
        if hold_steps < 0 or not 0.0 <= lr_scale <= 1.0:
            raise ValueError(f"hold_steps must be 0 or more and lr_scale in [0, 1]; got {hold_steps}, {lr_scale}")
        super().__init__(params, lr=lr, **kwargs)
        for group in self.param_groups:
            group.update(hold_steps=int(hold_steps), lr_scale=float(lr_scale), steps_taken=0)

    def step(self, closure: Callable[[], float] | None = None) -> float | None:
        group = self.param_groups[0]
        group_steps = group["steps_taken"] + 1
        for each in self.param_groups:
            each["steps_taken"] = group_steps
        if group_steps <= group["hold_steps"] or group["lr_scale"] == 0.0:
            return None
        rates = [each["lr"] for each in self.param_groups]
        for each in self.param_groups:
            each["lr"] = each["lr"] * each["lr_scale"]
        try:
            return super().step(closure)
        finally:
            for each, rate in zip(self.param_groups, rates):
                each["lr"] = rate
