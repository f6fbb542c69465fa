"""Is the Polyak-averaged target actor of a DDPG/TD3 run steadier than the actor it trails?

DDPG and TD3 keep a target copy of the actor, moved towards the actor by ``tau`` (0.005) after every
gradient step: an exponential average of the actor's weights over roughly the last 200 updates. The run
exports the actor itself. This writes both from a finished run's ``policy.zip`` (the best periodic
evaluation's whole model; pickle inside, so only for runs you made) as safe actor files that ``eval`` and
``stress`` take, with the run's sidecar metadata:

    .venv/bin/python experiments/target_actor.py runs/RUN --out out/target/RUN
    .venv/bin/autoscoop stress --policy out/target/RUN/target.safetensors --episodes 100 --cases heavy randomized
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from autoscoop.agents.algorithms import ALGORITHMS
from autoscoop.agents.policy_files import actor_from_sb3, save_actor

SIDECAR_KEYS = ("algo", "seed", "episodes", "run", "state_frame")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a finished DDPG/TD3 run directory (its policy.zip is loaded: pickle)")
    parser.add_argument("--out", type=Path, required=True, help="folder for online.safetensors and target.safetensors")
    args = parser.parse_args()
    info = json.loads((args.run / "policy.json").read_text())
    algo = ALGORITHMS[info["algo"]]
    model = algo.load(args.run / "policy.zip", device="cpu")
    metadata = {key: info[key] for key in SIDECAR_KEYS if key in info}
    args.out.mkdir(parents=True, exist_ok=True)
    save_actor(actor_from_sb3(model), args.out / "online.safetensors", metadata)
    save_actor(actor_from_sb3(model, target=True), args.out / "target.safetensors", {**metadata, "target_actor": True})
    print(f"wrote {args.out}/online.safetensors and target.safetensors")


if __name__ == "__main__":
    main()
