"""Does a policy cut less when its load reading says the earth is heavier?

A controller that stops by the load it reads takes fewer particles of heavy earth. This runs a policy on
the nominal pile once per scale, with the state's fill factor w (index 0, what the load cell or the
particle count gives) multiplied by ``--scale`` before the policy sees it, as if each particle weighed that
many times more. The scoop's particle count and volumetric fill show whether the actor's cut answers the
reading at all (the environment, the reward and the true load are untouched).

    .venv/bin/python experiments/load_reading_probe.py --policy runs/RUN --scales 1,1.33,0.67 --episodes 50
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig
from autoscoop.core.state import STATE_NAMES
from autoscoop.evaluation.evaluate import evaluate

FILL_INDEX = STATE_NAMES.index("w")


class ScaledLoadReading:
    """A policy whose state's w is multiplied by ``scale`` before it acts; everything else passes through."""

    def __init__(self, policy: Any, scale: float) -> None:
        self.policy, self.scale = policy, scale
        self.name = f"{policy.name} (w x {scale:g})"
        self.state_frame = getattr(policy, "state_frame", None)

    def reset(self) -> None:
        self.policy.reset()

    def act(self, observation: np.ndarray) -> np.ndarray:
        seen = np.array(observation, dtype=np.float32, copy=True)
        seen[FILL_INDEX] *= self.scale
        return self.policy.act(seen)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", required=True)
    parser.add_argument("--scales", default="1,1.33", help="comma-separated factors on the reading w")
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    config = ScoopConfig()
    for scale in (float(s) for s in args.scales.split(",")):
        policy = ScaledLoadReading(load_policy(args.policy, config), scale)
        outcomes = evaluate(policy, config, args.episodes, seed=args.seed, progress=False)
        particles = [o.particles for o in outcomes]
        volume = [o.volumetric_fill for o in outcomes]
        print(f"w x {scale:g}: particles {np.mean(particles):.1f} ± {np.std(particles):.1f}, volumetric "
              f"{np.mean(volume):.3f} ± {np.std(volume):.3f}, success {np.mean([o.success for o in outcomes]):.2f}",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
