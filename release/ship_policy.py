"""Ship a trained policy as the package's ``default``, with its metrics beside it.

``.venv/bin/python release/ship_policy.py RUN_DIR`` copies ``RUN_DIR/policy.safetensors`` and its
``.json`` (or, with ``--file``, a snapshot such as ``RUN_DIR/evaluated/episode_00700.safetensors``, picked by
``release/select_policy.py``) to ``autoscoop/policies/default.*``, evaluates it on the three public piles (25, 32, 40
degrees; 100 episodes each, seeds 0-99) and writes ``autoscoop/policies/default.metrics.json``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

POLICIES = Path(__file__).resolve().parent.parent / "autoscoop" / "policies"
KEYS = ("fill_factor_mean", "fill_factor_std", "mass_kg_mean", "mass_kg_std", "cycle_time_mean", "cycle_time_std",
        "success_rate", "spillage_mean", "physics_errors", "episodes")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--file", type=Path, help="a snapshot of the run to ship instead of RUN_DIR/policy.safetensors")
    parser.add_argument("--note", default="", help="how the policy was made, where the run directory does not say")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--angles", type=float, nargs="+", default=[25.0, 32.0, 40.0])
    args = parser.parse_args()
    POLICIES.mkdir(exist_ok=True)
    source = args.file or args.run_dir / "policy.safetensors"
    for suffix in (".safetensors", ".json"):
        shutil.copy(source.with_suffix(suffix), POLICIES / f"default{suffix}")
    run = json.loads((args.run_dir / "run.json").read_text())
    metrics = {"source_run": args.run_dir.name, "source_file": str(source.relative_to(args.run_dir)), "algo": run["algo"], "seed": run["seed"],
               "training_episodes": run["episodes"], "training_wall_s": run.get("wall_s"),
               "training_config": (args.run_dir / "config.yaml").read_text(), "piles": {}}
    if "selected_episode" in run:  # the recipe's selection chose this snapshot (selection.json in the run)
        metrics["selected_episode"] = run["selected_episode"]
    if args.note:
        metrics["note"] = args.note
    for angle in args.angles:
        out = args.run_dir / f"ship_eval_{angle:g}deg.json"
        subprocess.run([sys.executable, "-m", "autoscoop.cli", "eval", "--policy", "default", "--episodes",
                        str(args.episodes), "--set", f"pile.angle_deg={angle:g}", "--json", str(out)],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        summary = json.loads(out.read_text())
        metrics["piles"][f"{angle:g}"] = {key: summary[key] for key in KEYS}
        print(f"{angle:g} deg: " + ", ".join(f"{k}={summary[k]:.3f}" if isinstance(summary[k], float) else f"{k}={summary[k]}"
                                          for k in KEYS), flush=True)
    (POLICIES / "default.metrics.json").write_text(json.dumps(metrics, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
