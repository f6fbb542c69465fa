"""A recipe's seed table: each seed's kept policy through the eleven stress cases, and the median over seeds.

For each run directory (one per training seed), runs the stress suite on its kept policy
(``policy.safetensors``; seeds ``--seed`` .. ``--seed + --episodes - 1`` in every case, as ``autoscoop stress``
does) and prints a Markdown table: per case, the success rate and the volumetric fill; the cases held by
the stress suite's own thresholds; and the run's wall time from its ``run.json`` and ``selection.json``
(training, validation). The median row gives each case's median success and volumetric fill over the seeds.
A run's stress figures are kept beside it (``RUN/stress{EPISODES}_seed{SEED}.json``, per-case statistics
only) and read back on the next call, so the table can be redrawn without simulating. An argument
``NAME=FILE`` takes an ``autoscoop stress --json`` file instead of a run.

``--adapt FILE`` reads the summary ``benchmarks/adapt_worlds.py`` writes instead and prints, per target world and
case, the interquartile mean over seeds of the success rate and the volumetric fill with their 95 % stratified
bootstrap intervals (:mod:`autoscoop.report.seed_stats`) and the share of seeds that hold the case, then how many
seeds pass (the target world held and no case of ``default``'s lost).

    .venv/bin/python release/seed_table.py runs/robust-s10 runs/robust-s11 ... --episodes 100 --workers 2 \\
        --json out/seed_table.json
    .venv/bin/python release/seed_table.py --adapt benchmarks/results/adapt/adapt_worlds.json
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

from autoscoop.core.config import ScoopConfig
from autoscoop.core.safe_files import write_json_atomically
from autoscoop.evaluation.stress import CASES, case_names, run_stress
from autoscoop.report.seed_stats import seed_reliability


def stress_summary(run: Path, episodes: int, seed: int, workers: int) -> dict:
    """The run's stress rows as ``{"rows": [{"case", "stats", "passed"}]}``: read from its cache, or measured."""
    cache = run / f"stress{episodes}_seed{seed}.json"
    if cache.is_file():
        return json.loads(cache.read_text())
    rows = run_stress(str(run / "policy.safetensors"), ScoopConfig(), episodes, seed=seed, workers=workers)
    summary = {"policy": str(run / "policy.safetensors"), "episodes": episodes, "seed": seed,
               "rows": [{"case": r.case.name, "stats": r.stats, "passed": r.passed} for r in rows]}
    write_json_atomically(cache, summary)
    return summary


def run_times(run: Path) -> dict:
    """Seed and wall times (s) a run records: training (``run.json``) and validation (``selection.json``)."""
    info = json.loads((run / "run.json").read_text())
    selection = run / "selection.json"
    validation = json.loads(selection.read_text()).get("wall_s") if selection.is_file() else None
    return {"seed": info.get("seed"), "recipe": info.get("recipe"), "train_s": info.get("wall_s"),
            "validation_s": validation, "total_s": info.get("total_wall_s")}


def seed_row(name: str, summary: dict, times: dict) -> dict:
    """One table row: per case success, volumetric fill, overload and pass; the nominal fill; times."""
    rows = {row["case"]: row for row in summary["rows"]}
    missing = [case for case in case_names() if case not in rows]
    if missing:
        raise ValueError(f"{name}: no stress row for {missing}")
    return {"name": name, **times,
            "nominal_fill": rows["nominal"]["stats"]["fill_factor_mean"],
            "success": {c: rows[c]["stats"]["success_rate"] for c in case_names()},
            "volumetric_fill": {c: rows[c]["stats"]["volumetric_fill_mean"] for c in case_names()},
            "overload": {c: rows[c]["stats"]["overload_rate"] for c in case_names()},
            "passed": {c: bool(rows[c]["passed"]) for c in case_names()}}


def markdown(rows: list[dict]) -> str:
    """The table: one row per seed, each case as ``success / volumetric fill``, then the medians."""
    cases = case_names()
    lines = ["| run | train (s) | validation (s) | nominal fill | " + " | ".join(cases) + " | cases held |",
             "|---|--:|--:|--:|" + "--:|" * len(cases) + "--:|"]

    def seconds(value: float | None) -> str:
        return "" if value is None else f"{value:.0f}"

    for row in rows:
        held = sum(row["passed"].values())
        cells = [f"{row['success'][c]:.2f} / {row['volumetric_fill'][c]:.2f}" for c in cases]
        lines.append(f"| {row['name']} | {seconds(row['train_s'])} | {seconds(row['validation_s'])} | "
                     f"{row['nominal_fill']:.2f} | " + " | ".join(cells) + f" | {held} of {len(cases)} |")
    medians = [f"{statistics.median(r['success'][c] for r in rows):.2f} / "
               f"{statistics.median(r['volumetric_fill'][c] for r in rows):.2f}" for c in cases]
    lines.append(f"| median | | | {statistics.median(r['nominal_fill'] for r in rows):.2f} | "
                 + " | ".join(medians) + " | |")
    return "\n".join(lines)


def adapt_markdown(world: str, table: dict[str, dict], runs: list[dict]) -> str:
    """One target world's Markdown table: per case, IQM [95 % interval] of success and fill, share of seeds holding."""
    def cell(figures: dict) -> str:
        return f"{figures['iqm']:.3f} [{figures['low']:.3f}, {figures['high']:.3f}]"

    seeds = ", ".join(str(run["seed"]) for run in runs)
    lines = [f"**{world}** (seeds {seeds}; {sum(run['passed'] for run in runs)} of {len(runs)} pass)", "",
             "| case | success, IQM [95 % CI] | volumetric fill, IQM [95 % CI] | seeds holding |",
             "|---|---|---|---|"]
    for case, row in table.items():
        lines.append(f"| {case} | {cell(row['success_rate'])} | {cell(row['volumetric_fill_mean'])} | "
                     f"{row['share_passed']:.0%} |")
    return "\n".join(lines)


def adapt_table(summary_file: Path, json_out: Path | None) -> int:
    """Print (and with ``json_out`` write) the reliability table of each target world in an adapt summary."""
    runs = json.loads(summary_file.read_text())["runs"]
    worlds = list(dict.fromkeys(run["world"] for run in runs))
    out = {}
    for world in worlds:
        mine = sorted((run for run in runs if run["world"] == world), key=lambda run: run["seed"])
        table = seed_reliability([run["by_case"] for run in mine])
        print(adapt_markdown(world, table, mine), end="\n\n")
        out[world] = {"seeds": [run["seed"] for run in mine], "seeds_passing": sum(run["passed"] for run in mine),
                      "adapt_wall_s": [run["adapt_wall_s"] for run in mine],
                      "scoops_simulated": [run["scoops_simulated"] for run in mine], "cases": table}
    if json_out:
        write_json_atomically(json_out, {"source": str(summary_file), "worlds": out})
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="*", metavar="RUN|NAME=FILE",
                        help="a finished run directory, or a row's name and an `autoscoop stress --json` file")
    parser.add_argument("--episodes", type=int, default=100, help="episodes per case for runs (default 100)")
    parser.add_argument("--seed", type=int, default=0, help="first evaluation seed (default 0: seeds 0-99)")
    parser.add_argument("--workers", type=int, default=2, help="stress worker processes (default 2)")
    parser.add_argument("--json", type=Path, help="write every row's figures to this JSON file")
    parser.add_argument("--adapt", type=Path, metavar="FILE",
                        help="the reliability table of an adapt benchmark's summary (benchmarks/adapt_worlds.py)")
    args = parser.parse_args()
    if args.adapt:
        return adapt_table(args.adapt, args.json)
    if not args.runs:
        parser.error("give run directories or NAME=FILE stress files, or --adapt FILE")
    if args.episodes < 1 or args.workers < 1 or args.seed < 0:
        parser.error("--episodes and --workers must be at least 1, --seed at least 0")
    rows = []
    for item in args.runs:
        name, sep, path = item.partition("=")
        if sep:  # a stress file; the times of the run it sits in, where it does
            beside = Path(path).parent
            times = run_times(beside) if (beside / "run.json").is_file() else dict.fromkeys(
                ("seed", "recipe", "train_s", "validation_s", "total_s"))
            rows.append(seed_row(name, json.loads(Path(path).read_text()), times))
            continue
        run = Path(item)
        if not (run / "run.json").is_file():
            parser.error(f"{run}: not a run directory (no run.json)")
        rows.append(seed_row(run.name, stress_summary(run, args.episodes, args.seed, args.workers), run_times(run)))
    table = markdown(rows)
    print(table)
    cases = case_names()
    every = all(all(r["passed"].values()) for r in rows)
    median_success = {c: statistics.median(r["success"][c] for r in rows) for c in cases}
    print(f"{sum(all(r['passed'].values()) for r in rows)} of {len(rows)} seeds hold every case; "
          f"lowest median success {min(median_success.values()):.2f} ({min(median_success, key=median_success.get)})")
    if args.json:
        write_json_atomically(args.json, {"episodes_per_case": args.episodes, "first_seed": args.seed,
                                          "cases": [case.name for case in CASES], "rows": rows,
                                          "median_success": median_success, "every_seed_holds_every_case": every,
                                          "markdown": table})
    return 0


if __name__ == "__main__":
    sys.exit(main())
