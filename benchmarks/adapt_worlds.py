"""Adapt the shipped policy to target worlds over several seeds, then stress each adapted policy.

For each world and seed: ``autoscoop adapt --policy default --set WORLD --seed S`` (timed, wall seconds of the
whole command; a run cut by an interruption is continued with ``--resume``), then the stress suite on its kept
policy (``default``'s figures where the run kept its starting weights unchanged) and on ``default``, the same
seeds in every case (``--episodes`` each, seeds 0 on): the target world
first, then the eleven stress cases. A run passes when its target world holds the stress thresholds and every
case ``default`` holds still holds, within ``--tolerance`` of ``default``'s success and volumetric fill.
Each run's figures go to ``OUT/WORLD-sS/stress{EPISODES}.json`` and a summary row to ``--json``; the seed table
(interquartile mean over seeds and its 95 % bootstrap interval, share of seeds passing) comes from
``release/seed_table.py --adapt FILE``.

    .venv/bin/python benchmarks/adapt_worlds.py --worlds heavy --seeds 0 1 2 3 4 --out runs/adapt-bench \\
        --json benchmarks/results/adapt/adapt_worlds.json
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from autoscoop.agents.loading import default_policy_path
from autoscoop.agents.policy_files import sha256_of
from autoscoop.core.config import ScoopConfig
from autoscoop.core.safe_files import write_json_atomically
from autoscoop.evaluation.stress import CASES, STRESS_THRESHOLDS, StressCase, run_stress

WORLDS = {
    "heavy": {"pile.particle_mass_kg": 0.4},
    "denser": {"pile.particle_mass_kg": 0.45},
    "randomized": {"randomize.preset": "robot"},
    "light_25": {"pile.angle_deg": 25.0, "pile.particle_mass_kg": 0.2},
}
"""the target worlds: heavy earth, denser earth (outside the training ranges), the randomised world, a 25 degree
pile of light earth."""


def target_case(world: str) -> StressCase:
    """The target world as a stress case, with the stress thresholds."""
    return StressCase(f"target_{world}", f"target world {world}", WORLDS[world], STRESS_THRESHOLDS)


def stress_rows(policy: str, world: str, episodes: int, seed: int, workers: int, cache: Path) -> list[dict]:
    """The target world's row and the stress cases' rows of ``policy`` (read from ``cache`` when there)."""
    if cache.is_file():
        return json.loads(cache.read_text())["rows"]
    rows = run_stress(policy, ScoopConfig(), episodes, seed=seed, workers=workers, progress=False,
                      cases=[target_case(world), *CASES])
    summary = {"policy": policy, "episodes": episodes, "seed": seed,
               "rows": [{"case": r.case.name, "stats": r.stats, "passed": r.passed} for r in rows]}
    write_json_atomically(cache, summary)
    return summary["rows"]


def verdict(rows: list[dict], reference: list[dict], tolerance: float) -> dict:
    """Whether the target world holds and no case the reference holds is lost (fails, or falls more than
    ``tolerance`` below it in success or volumetric fill)."""
    before = {row["case"]: row for row in reference}
    lost = []
    for row in rows[1:]:
        ref = before[row["case"]]
        if not ref["passed"]:
            continue
        drops = {metric: ref["stats"][metric] - row["stats"][metric] for metric in ("success_rate", "volumetric_fill_mean")}
        if not row["passed"] or any(drop > tolerance + 1e-9 for drop in drops.values()):
            lost.append({"case": row["case"], "passed": row["passed"], **{f"drop_{k}": round(v, 4) for k, v in drops.items()}})
    return {"target_passed": rows[0]["passed"], "lost": lost, "passed": rows[0]["passed"] and not lost}


def adapt_run(world: str, seed: int, out: Path, extra: list[str]) -> float:
    """Run (or continue) ``autoscoop adapt`` for ``world`` and ``seed`` into ``out``; return its wall seconds."""
    info = out / "run.json"
    if info.is_file() and (out / "selection.json").is_file() and (out / "policy.onnx").is_file():
        return float(json.loads(info.read_text()).get("command_wall_s", float("nan")))
    command = [sys.executable, "-m", "autoscoop.cli", "adapt", "--no-progress"]
    if info.is_file():
        command += ["--resume", str(out)]
    else:
        command += ["--policy", "default", "--seed", str(seed), "--out", str(out), *extra]
        for key, value in WORLDS[world].items():
            command += ["--set", f"{key}={value}"]
    started = time.monotonic()
    subprocess.run(command, check=True)
    return round(time.monotonic() - started, 1)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--worlds", default=",".join(WORLDS), help=f"comma-separated, of {', '.join(WORLDS)}")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--episodes", type=int, default=100, help="stress episodes per case (seeds 0 on)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--tolerance", type=float, default=0.03)
    parser.add_argument("--out", type=Path, required=True, help="folder of the adapt runs")
    parser.add_argument("--json", type=Path, required=True, help="summary rows, one per world and seed")
    parser.add_argument("--adapt-args", default="", help="more options for autoscoop adapt, e.g. '--episodes 600'")
    args = parser.parse_args()
    worlds = [w for w in args.worlds.split(",") if w]
    unknown = sorted(set(worlds) - set(WORLDS))
    if unknown:
        parser.error(f"unknown worlds {unknown}; known: {', '.join(WORLDS)}")
    summary = json.loads(args.json.read_text()) if args.json.is_file() else {"runs": []}
    done = {(r["world"], r["seed"]) for r in summary["runs"]}
    for world in worlds:
        reference = stress_rows("default", world, args.episodes, 0, args.workers,
                                args.out / f"default-{world}-stress{args.episodes}.json")
        for seed in args.seeds:
            if (world, seed) in done:
                continue
            run = args.out / f"{world}-s{seed}"
            wall = adapt_run(world, seed, run, args.adapt_args.split())
            info = json.loads((run / "run.json").read_text())
            kept_start = sha256_of(run / "policy.safetensors") == sha256_of(default_policy_path())
            # the same weights on the same seeds give the same figures: a run that kept its start is default's
            rows = reference if kept_start else stress_rows(str(run / "policy.safetensors"), world, args.episodes, 0,
                                                            args.workers, run / f"stress{args.episodes}.json")
            row = {"world": world, "seed": seed, "run": str(run), "adapt_wall_s": wall,
                   "training_wall_s": info.get("wall_s"), "scoops_simulated": info.get("scoops_simulated"),
                   "selected_episode": info.get("selected_episode"), "kept_start": kept_start, **verdict(rows, reference, args.tolerance),
                   "by_case": {r["case"]: {k: r["stats"][k] for k in ("success_rate", "volumetric_fill_mean",
                                                                       "fill_factor_mean", "overload_rate")}
                               | {"passed": r["passed"]} for r in rows},
                   "default_by_case": {r["case"]: {k: r["stats"][k] for k in ("success_rate", "volumetric_fill_mean",
                                                                               "fill_factor_mean", "overload_rate")}
                                       | {"passed": r["passed"]} for r in reference}}
            summary["runs"].append(row)
            write_json_atomically(args.json, summary)
            print(f"{world} s{seed}: target {'holds' if row['target_passed'] else 'FAILS'}, lost "
                  f"{[c['case'] for c in row['lost']]}, adapt {wall} s, {row['scoops_simulated']} scoops", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
