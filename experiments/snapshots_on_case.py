"""Each snapshot of a run on chosen stress cases, with more episodes than the validation suite.

The recipe's validation suite (``selection.json``) runs each candidate 20 episodes per case. This runs
every candidate it names again on the given cases (default: heavy), ``--episodes`` each from seed
``--seed`` (1000: apart from the validation's 20000 on and the reports' 0-99), and prints, per
candidate, its validation success and shortfall beside success / volumetric fill / overload per case:
whether any snapshot of the run holds a case, or the choice among them cannot help. With
``--snapshots N`` the candidates are instead the run's N best evaluated snapshots of its last world by the
periodic evaluation (those the validation would see if it took N), and ``--json`` keeps every figure.

    .venv/bin/python experiments/snapshots_on_case.py runs/RUN --cases heavy --episodes 40
    .venv/bin/python experiments/snapshots_on_case.py runs/RUN --snapshots 16 --cases heavy,randomized \
        --episodes 100 --seed 20000 --workers 2 --json out/spread.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from autoscoop.core.config import ScoopConfig
from autoscoop.core.safe_files import write_json_atomically
from autoscoop.evaluation.stress import run_stress, select_cases


def candidates_of(run_dir: Path, snapshots: int | None) -> list[dict]:
    """The validated candidates of ``selection.json``, or the ``snapshots`` best evaluated snapshots of the last world."""
    if snapshots:
        from autoscoop.commands.train_cmd import last_world_snapshots  # noqa: PLC0415 - torch is slow to import

        found, _ = last_world_snapshots(run_dir, snapshots)
        return [{"name": f"episode {episode}", "path": str(path), "periodic": score} for episode, score, path in found]
    selection = run_dir / "selection.json"
    if not selection.is_file():
        raise SystemExit(f"{selection} not found: the run has made no validated choice (or give --snapshots N)")
    return json.loads(selection.read_text())["candidates"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir", type=Path, help="a training run")
    parser.add_argument("--cases", default="heavy", help="stress cases, comma-separated (default heavy)")
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--snapshots", type=int, default=None,
                        help="the N best evaluated snapshots instead of selection.json's candidates")
    parser.add_argument("--workers", type=int, default=1, help="cases run in parallel")
    parser.add_argument("--json", type=Path, default=None, help="write every candidate's figures here")
    args = parser.parse_args()
    cases = select_cases(args.cases)
    results = []
    for candidate in candidates_of(args.run_dir, args.snapshots):
        rows = run_stress(candidate["path"], ScoopConfig(), args.episodes, seed=args.seed, cases=cases,
                          workers=args.workers, progress=False)
        stats = {row.case.name: {key: row.stats[key] for key in
                                 ("success_rate", "volumetric_fill_mean", "fill_factor_mean", "overload_rate",
                                  "cycle_time_mean")} | {"passed": row.passed} for row in rows}
        results.append({"name": candidate["name"], "path": candidate["path"],
                        "periodic": candidate.get("periodic"), "shortfall": candidate.get("shortfall"),
                        "by_case": stats})
        cells = [f"{name}: {s['success_rate']:.2f} / {s['volumetric_fill_mean']:.2f} / {s['overload_rate']:.2f}"
                 for name, s in stats.items()]
        validated = candidate.get("by_case", {}).get(cases[0].name, {}).get("success_rate")
        print(f"{candidate['name']}: validation {cases[0].name} success {validated}, shortfall "
              f"{candidate.get('shortfall')}; {'; '.join(cells)}", flush=True)
    if args.json:
        write_json_atomically(args.json, {"run": str(args.run_dir), "cases": [c.name for c in cases],
                                          "episodes": args.episodes, "seed": args.seed, "candidates": results},
                              indent=1)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
