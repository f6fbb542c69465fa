"""Can the robot's readings tell the earth's weight while the cut can still change?

A deployable actor (and a student distilled from a teacher that sees the material) can only cut by the
load if its own readings carry the particle mass early enough. This runs one policy over stress cases of
different particle mass (same seeds, so the same piles), records the robot's state (the actor's 12
numbers; :mod:`autoscoop.core.state`) and the joint torques at every control period, and asks how well a
ridge regression on the readings of the last ``--window`` periods before an event predicts the particle
mass. Events: the tip first under the pile's face (and one and two periods later), the first particle in
the bucket, and the bucket holding 5 and 10 particles. In a randomised world (``--cases randomized``) every
episode draws its own mass, and friction, pile, delay and noise beside it. The regression is validated by seed (the folds never share a pile), so the
figures say what a reading carries, not what one pile looks like.

    .venv/bin/python experiments/load_inference_probe.py --policy default --cases nominal,light,heavy \\
        --episodes 100 --json out/load_inference.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig
from autoscoop.core.safe_files import write_json_atomically
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.evaluation.stress import select_cases

EVENTS = ("contact", "contact+1", "contact+2", "first_particle", "particles_5", "particles_10")


def record_episode(policy, env, seed: int) -> dict:
    """Per-period state, torques, particle count and penetration of one episode."""
    states, torques, particles, penetrating = [], [], [], []

    def observe(step, obs, action, reward, info):
        states.append(np.asarray(obs, dtype=float)[:12])
        torques.append([info.get("lift_torque_nm", 0.0), info.get("tilt_torque_nm", 0.0)])
        particles.append(int(info.get("particles_in_bucket", 0)))
        penetrating.append(bool(info.get("penetrating", False)))

    outcome = rollout(policy, env, seed, observers=[observe])
    return {"states": np.array(states), "torques": np.nan_to_num(np.array(torques, dtype=float)),
            "particles": np.array(particles), "penetrating": np.array(penetrating), "final": outcome.particles}


def event_step(episode: dict, event: str) -> int | None:
    """The first period at which ``event`` holds, or None."""
    if event.startswith("contact"):
        hits = np.flatnonzero(episode["penetrating"])
        later = int(event.partition("+")[2] or 0)
        return min(int(hits[0]) + later, len(episode["states"]) - 1) if hits.size else None
    else:
        need = {"first_particle": 1, "particles_5": 5, "particles_10": 10}[event]
        hits = np.flatnonzero(episode["particles"] >= need)
    return int(hits[0]) if hits.size else None


def window_features(episode: dict, step: int, window: int, with_torques: bool, with_w: bool) -> np.ndarray:
    """The readings of periods step-window+1 .. step (the first period repeated before the episode's start)."""
    rows = []
    for k in range(step - window + 1, step + 1):
        k = max(k, 0)
        state = episode["states"][k].copy()
        if not with_w:
            state = state[1:]
        rows.append(np.concatenate([state, episode["torques"][k]]) if with_torques else state)
    return np.concatenate(rows)


def ridge_by_seed(x: np.ndarray, y: np.ndarray, seeds: np.ndarray, folds: int = 5, alpha: float = 1.0) -> np.ndarray:
    """Out-of-fold predictions of a ridge regression on standardised features, folds split by seed."""
    predictions = np.zeros_like(y)
    unique = np.unique(seeds)
    for f in range(folds):
        held = np.isin(seeds, unique[f::folds])
        mean, std = x[~held].mean(0), x[~held].std(0) + 1e-9
        a = (x[~held] - mean) / std
        b = y[~held] - y[~held].mean()
        w = np.linalg.solve(a.T @ a + alpha * len(a) * np.eye(a.shape[1]), a.T @ b)
        predictions[held] = (x[held] - mean) / std @ w + y[~held].mean()
    return predictions


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", default="default")
    parser.add_argument("--cases", default="nominal,light,heavy")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--window", type=int, default=4, help="control periods of readings before the event")
    parser.add_argument("--alpha", type=float, default=0.01, help="ridge penalty (per sample, on standardised features)")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)

    episodes, masses, seeds = [], [], []
    for case in select_cases(args.cases):
        config = case.config(ScoopConfig())
        env = make_scoop_env(config)
        policy = load_policy(args.policy, config)
        for i in range(args.episodes):
            episodes.append(record_episode(policy, env, args.seed + i))
            masses.append(env.unwrapped.episode_config.pile.particle_mass_kg)
            seeds.append(args.seed + i)
        env.close()
        print(f"{case.name}: {args.episodes} episodes recorded", flush=True)
    masses, seeds = np.array(masses), np.array(seeds)
    finals = np.array([e["final"] for e in episodes])
    levels = np.unique(masses)
    results: dict = {"policy": args.policy, "cases": args.cases, "episodes_per_case": args.episodes,
                     "window": args.window, "particles_by_mass": {}, "events": {}}
    discrete = len(levels) <= 5  # the stress cases' masses; a randomised world draws a mass per episode
    groups = ([(f"{m:g}", masses == m) for m in levels] if discrete else
              [(f"{lo:.3f}-{hi:.3f}", (masses >= lo) & (masses <= hi))
               for lo, hi in zip(*(lambda q: (q[:-1], q[1:]))(np.quantile(masses, [0, 1 / 3, 2 / 3, 1])))])
    for label, members in groups:
        results["particles_by_mass"][label] = [round(float(finals[members].mean()), 2),
                                               round(float(finals[members].std()), 2)]
    for event in EVENTS:
        steps = [event_step(e, event) for e in episodes]
        keep = np.array([s is not None for s in steps])
        row: dict = {"episodes": int(keep.sum()),
                     "period_mean": round(float(np.mean([s for s in steps if s is not None])), 2)}
        for label, torques, with_w in (("state", False, True), ("state_without_w", False, False),
                                       ("state_and_torques", True, True)):
            x = np.array([window_features(e, s, args.window, torques, with_w)
                          for e, s in zip(episodes, steps) if s is not None])
            y, g = masses[keep], seeds[keep]
            predicted = ridge_by_seed(x, y, g, alpha=args.alpha)
            r2 = 1.0 - np.sum((predicted - y) ** 2) / np.sum((y - y.mean()) ** 2)
            row[label] = {"r2": round(float(r2), 3), "rmse_kg": round(float(np.sqrt(np.mean((predicted - y) ** 2))), 4)}
            if discrete:  # the share of episodes whose nearest mass level is the drawn one
                nearest = levels[np.argmin(np.abs(predicted[:, None] - levels[None, :]), axis=1)]
                row[label]["accuracy"] = round(float(np.mean(nearest == y)), 3)
        results["events"][event] = row
        print(event, row, flush=True)
    print("particles by mass (mean, std):", results["particles_by_mass"])
    if args.json:
        write_json_atomically(args.json, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
