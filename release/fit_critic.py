"""Fit a critic to a shipped actor that has none, so that ``autoscoop adapt`` can fine-tune it.

``.venv/bin/python release/fit_critic.py --recipe robot_smooth --episodes 1000 --out runs/critic-fit`` trains
the paper's critic (asymmetric, as the recipe's) from fresh weights on the shipped ``default`` actor, which holds
still the whole run (:class:`autoscoop.agents.optimizers.HeldAdam` with no step): the recipe's reward, discount
and privileged numbers, one simulator in the recipe's last world (the randomised ``robot`` world) and one more in
the same world with other seeds, exploration noise ``--noise-sigma`` around the actor's actions. It then writes
``autoscoop/policies/default.critic.safetensors`` and ``.json``: the critic, its target, the recipe, the recipe's
base world and its last world, and the SHA-256 of the actor it belongs to (checked: the run's actor must be the
shipped one, bit for bit). ``--resume RUN`` continues a cut fit with ``autoscoop adapt --resume RUN`` first.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

from autoscoop.agents.critic_files import critic_path_for, read_critic_sidecar
from autoscoop.agents.loading import default_policy_path
from autoscoop.agents.policy_files import sha256_of
from autoscoop.core.config import ScoopConfig
from autoscoop.core.safe_files import write_json_atomically
from autoscoop.training.adapt import AdaptArgs, AdaptSource, adapt
from autoscoop.training.settings import config_at, load_recipe

FROZEN = 1 << 40
"""gradient steps the actor holds for: all of them."""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--recipe", default="robot_smooth", help="the recipe the shipped actor was trained with")
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--noise-sigma", type=float, default=0.1)
    parser.add_argument("--out", type=Path, required=True, help="the fit's run directory")
    args = parser.parse_args()
    spec = load_recipe("ddpg", args.recipe)
    base = ScoopConfig().with_overrides(spec.get("env") or {})
    held = config_at(base, spec, 1 << 30)
    actor = default_policy_path()
    meta = {"spec": spec, "config": base.to_dict(), "held_config": held.to_dict(), "algo": "ddpg"}
    if not (args.out / "run.json").is_file():
        source = AdaptSource("default", actor, None, meta)
        adapt(AdaptArgs(policy="default", overrides={"randomize.preset": held.randomize.preset},
                        episodes=args.episodes, seed=args.seed, critic_warmup_steps=FROZEN, noise_sigma=args.noise_sigma,
                        eval_every=args.episodes, out=args.out), source=source)
    fitted = args.out / "critic.safetensors"
    fitted_meta = read_critic_sidecar(fitted)
    if fitted_meta["actor_sha256"] != sha256_of(actor):
        print(f"the fit's actor is not the shipped one (SHA-256 {fitted_meta['actor_sha256']}); nothing written",
              file=sys.stderr)
        return 1
    target = critic_path_for(actor)
    shutil.copyfile(fitted, target)
    write_json_atomically(target.with_suffix(".json"),
                          {**fitted_meta, **meta, "run": args.out.name, "fitted_episodes": args.episodes,
                           "fitted_noise_sigma": args.noise_sigma, "recipe": args.recipe})
    print(f"wrote {target} and {target.with_suffix('.json').name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
