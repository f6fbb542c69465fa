"""Can evolution strategies move an actor where DDPG fine-tuning stalls? (the 25 degree pile of light earth)

``autoscoop adapt`` fine-tunes with DDPG's deterministic policy gradient. During the cut the shipped actor's
commands sit at the ends of their range (drive, lift and tilt at 0.93-0.99 of full scale), where the tanh output
passes almost no gradient; in the 25 degree pile of light earth its fine-tuned actors stall at success 0.82-0.88.
Evolution strategies need no gradient through the actor: this script perturbs the actor's weights (antithetic
pairs, ``--sigma``), runs each perturbed actor on the same episode seeds (common random numbers, 40000 on, a
thousand apart per iteration), ranks them and steps the weights with Adam (OpenAI-ES, Salimans et al., 2017).

Each perturbed actor's fitness is its mean episode score in the target world plus a term for the guard cases
(``--held CASE:EPISODES,...``, the stress cases); an episode scores success (0 or 1) plus its volumetric fill (paid
up to 0.72, the nominal scoop's) minus 2 for an overload. ``--fitness sum`` adds the guard cases' mean score (times ``--held-weight``);
``--fitness guard`` adds ``--guard-weight`` times the sum over the guard cases of how far each falls more than
0.05 below the starting actor on the same seeds (nothing for gains). Each iterate is written as
``OUT/itNNN.safetensors``; check one with ``autoscoop stress --policy OUT/it006.safetensors --episodes 100``.

    .venv/bin/autoscoop adapt --policy default --set pile.particle_mass_kg=0.2 --set pile.angle_deg=25 \\
        --set reward.c_w=100 --set reward.c_success=50 --episodes 800 --actor-lr-scale 0.05 --target-envs 2 \\
        --candidates 6 --seed 0 --out runs/l25-e1-s0
    .venv/bin/python experiments/adapt_evolution.py runs/l25-e1-s0/evaluated/episode_00375.safetensors \\
        runs/es-sum 7 --fitness sum --held angle_25:4,heavy:4,light:4,randomized:4 --pop 8 --target-episodes 12
"""

from __future__ import annotations

import argparse
import copy
import json
import shutil
import time
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import torch

from autoscoop.agents.policy_files import ActorPolicy, load_actor, save_actor
from autoscoop.core.config import ScoopConfig
from autoscoop.core.safe_files import write_json_atomically
from autoscoop.evaluation.evaluate import evaluate
from autoscoop.evaluation.stress import CASES, STRESS_THRESHOLDS, StressCase

FILL_PAID_UP_TO = 0.72
"""volumetric fill above this (the nominal scoop's) earns nothing more."""
GUARD_TOLERANCE = 0.05
"""how far a guard case's score may fall below the starting actor's before the guard term counts it."""

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("start", help="the actor to start from (.safetensors)")
parser.add_argument("out", type=Path, help="folder for the iterates and es.json")
parser.add_argument("iterations", type=int)
parser.add_argument("--pop", type=int, default=6, help="antithetic pairs per iteration")
parser.add_argument("--sigma", type=float, default=0.02, help="perturbation, weight units")
parser.add_argument("--lr", type=float, default=0.01, help="Adam's step, weight units")
parser.add_argument("--target", default="pile.angle_deg=25,pile.particle_mass_kg=0.2", help="KEY=VALUE,...")
parser.add_argument("--target-episodes", type=int, default=10)
parser.add_argument("--held", default="angle_25:4,heavy:8,light:2,torque_mass:4,randomized:8")
parser.add_argument("--fitness", choices=("sum", "guard"), default="guard")
parser.add_argument("--guard-weight", type=float, default=2.0)
parser.add_argument("--held-weight", type=float, default=1.0, help="with --fitness sum: weight of the guard cases' mean")
parser.add_argument("--workers", type=int, default=2)
args = parser.parse_args()

TARGET = StressCase("target", "target world",
                    {k: float(v) for k, v in (kv.split("=") for kv in args.target.split(","))}, STRESS_THRESHOLDS)
HELD_EPISODES = {name: int(n) for name, n in (kv.split(":") for kv in args.held.split(","))}
HELD = [case for case in CASES if case.name in HELD_EPISODES]
START, METADATA = load_actor(args.start)
METADATA = {k: v for k, v in METADATA.items() if k != "sha256"}  # each iterate's own hash is written


def actor_with(weights: np.ndarray) -> torch.nn.Module:
    actor = copy.deepcopy(START)
    torch.nn.utils.vector_to_parameters(torch.as_tensor(weights, dtype=torch.float32), actor.parameters())
    return actor


def episode_score(outcome) -> float:
    """Success (0 or 1) plus the volumetric fill paid up to :data:`FILL_PAID_UP_TO`, minus 2 for an overload."""
    return float(outcome.success) + min(outcome.volumetric_fill, FILL_PAID_UP_TO) - 2.0 * float(outcome.overloaded)


def fitness_parts(job: tuple[int, np.ndarray, int]) -> tuple[float, list[float], float]:
    """One candidate's mean score in the target world, its mean score in each guard case, its target success."""
    index, weights, seed = job
    torch.set_num_threads(1)
    folder = args.out / "work"
    folder.mkdir(parents=True, exist_ok=True)
    policy = ActorPolicy(save_actor(actor_with(weights), folder / f"candidate{index}.safetensors", METADATA))
    target = evaluate(policy, TARGET.config(ScoopConfig()), args.target_episodes, seed=seed, progress=False)
    held = [float(np.mean([episode_score(o) for o in evaluate(policy, case.config(ScoopConfig()),
                                                               HELD_EPISODES[case.name], seed=seed + 500,
                                                               progress=False)]))
            for case in HELD]
    return float(np.mean([episode_score(o) for o in target])), held, float(np.mean([o.success for o in target]))


def centred_ranks(values: np.ndarray) -> np.ndarray:
    ranks = np.empty(len(values))
    ranks[np.argsort(values)] = np.arange(len(values))
    return ranks / (len(values) - 1) - 0.5


def main() -> None:
    args.out.mkdir(parents=True, exist_ok=True)
    start = torch.nn.utils.parameters_to_vector(START.parameters()).detach().numpy().astype(np.float64)
    weights = start.copy()
    first, second = np.zeros_like(weights), np.zeros_like(weights)
    rng = np.random.default_rng(0)
    log = []
    with get_context("fork").Pool(args.workers) as pool:
        for iteration in range(args.iterations):
            began = time.time()
            noise = rng.standard_normal((args.pop, weights.size))
            seed = 40000 + 1000 * iteration
            candidates = ([weights + args.sigma * e for e in noise] + [weights - args.sigma * e for e in noise]
                          + [weights, start])
            parts = pool.map(fitness_parts, [(i, c, seed) for i, c in enumerate(candidates)])
            reference = np.array(parts[-1][1])
            if args.fitness == "sum":
                fitness = np.array([t + args.held_weight * float(np.mean(h)) for t, h, _ in parts[:-2]])
            else:
                fitness = np.array([t + args.guard_weight * float(np.minimum(0.0, np.array(h) - reference + GUARD_TOLERANCE).sum())
                                    for t, h, _ in parts[:-2]])
            ranks = centred_ranks(fitness)
            gradient = ((ranks[:args.pop] - ranks[args.pop:]) @ noise) / (2 * args.pop * args.sigma)
            first = 0.9 * first + 0.1 * gradient
            second = 0.999 * second + 0.001 * gradient ** 2
            weights = weights + args.lr * (first / (1 - 0.9 ** (iteration + 1))) / (
                np.sqrt(second / (1 - 0.999 ** (iteration + 1))) + 1e-8)
            save_actor(actor_with(weights), args.out / f"it{iteration:03d}.safetensors", METADATA)
            centre = parts[-2]
            row = {"iteration": iteration, "centre_target_score": round(centre[0], 3),
                   "centre_target_success": round(centre[2], 2),
                   "centre_guard_minus_start": {c.name: round(h - r, 2) for c, h, r in zip(HELD, centre[1], reference, strict=True)},
                   "population_mean": round(float(fitness.mean()), 3), "wall_s": round(time.time() - began, 1)}
            log.append(row)
            print(json.dumps(row), flush=True)
            write_json_atomically(args.out / "es.json", {"settings": vars(args) | {"out": str(args.out)}, "iterations": log})
    shutil.rmtree(args.out / "work", ignore_errors=True)  # the candidates' files


if __name__ == "__main__":
    main()
