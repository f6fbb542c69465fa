"""Why scoops of heavy earth fail: the chassis pitch and the bucket's height, episode by episode.

On 0.4 kg particles a scoop of about 7 kg, lifted while the bucket is still under the pile, tips the
loader forward onto its front wheels. This runs a controller on the stress suite's ``heavy`` case
(``pile.particle_mass_kg=0.4``) for the given seeds and prints, per episode, whether it succeeded, the
particles in the bucket, the largest chassis pitch (degrees, positive: nose down), the mean pitch over
the last 2 s, the highest the tip rose (world z, m; the terminal point is ``reward.terminal_z_m`` high)
and how close the tip came to the terminal point (m; success needs ``reward.epsilon_m``).

    .venv/bin/python experiments/heavy_failures.py --policy default --seeds 0-99 [--failed-only]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.sim.load_cell import chassis_pitch_rad

LAST_STEPS = 8
"""control periods at an episode's end over which the pitch is averaged (2 s)."""


def parse_seeds(text: str) -> list[int]:
    """``0-99`` or ``1,5,10`` (or a mix) -> the seeds."""
    seeds: list[int] = []
    for part in text.split(","):
        low, _, high = part.partition("-")
        seeds.extend(range(int(low), int(high or low) + 1))
    return seeds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", default="default", help="default, heuristic or a policy file")
    parser.add_argument("--seeds", default="0-99", help="e.g. 0-99 or 1,5,10")
    parser.add_argument("--mass", type=float, default=0.4, help="particle mass, kg (default 0.4: the heavy case)")
    parser.add_argument("--failed-only", action="store_true", help="print only the episodes that failed")
    args = parser.parse_args()
    config = ScoopConfig().with_overrides({"pile.particle_mass_kg": args.mass})
    policy = load_policy(args.policy, config)
    env = make_scoop_env(config)
    sim_env = env.unwrapped
    print("seed success particles max_pitch_deg last_2s_pitch_deg max_tip_z_m closest_to_terminal_m")
    counts = {"success": [], "failed": []}
    for seed in parse_seeds(args.seeds):
        pitches, heights, closest = [], [], []

        def watch(_step, _obs, _action, _reward, info, pitches=pitches, heights=heights, closest=closest):
            pitches.append(math.degrees(chassis_pitch_rad(sim_env.sim)))
            heights.append(float(sim_env.sim.tip_world[2]))
            closest.append(float(info["tip_to_terminal_m"]))

        outcome = rollout(policy, env, seed, [watch])
        counts["success" if outcome.success else "failed"].append(max(pitches))
        if args.failed_only and outcome.success:
            continue
        print(f"{seed} {outcome.success} {outcome.particles} {max(pitches):.1f} {np.mean(pitches[-LAST_STEPS:]):.1f} "
              f"{max(heights):.3f} {min(closest):.3f}")
    for name, values in counts.items():
        if values:
            print(f"{name}: {len(values)} episodes, largest pitch {min(values):.1f}-{max(values):.1f} deg "
                  f"(median {np.median(values):.1f})")
    env.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
