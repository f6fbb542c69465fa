"""Train a machine's controller on several seeds, stress each and its scripted scoop, and judge them against
the scripted scoop: each kept policy must fill >= 0.70 of the rated load with success >= 0.95 on the nominal
pile, with a mean cycle no longer than the scripted scoop's, and hold at least as many of the 11 stress cases.

For each seed: ``autoscoop train --machine M --recipe R --seed S --out OUT/M-sS`` (a run cut by an interruption
is continued with ``--resume``; one that finished is kept), then ``autoscoop stress --machine M --policy RUN
--episodes N --json OUT/stress-sS.json``; the scripted scoop's stress is ``OUT/stress-heuristic.json``. With ``--adapt-from OTHER`` each seed is
instead a warm start from another machine's shipped controller, ``autoscoop adapt --machine M --policy default
--from-machine OTHER --seed S --out OUT/M-sS`` (``--train-args`` then go to ``adapt``). Every
stress case runs seeds 0 to N-1. The summary (``--json``) holds, per policy, the nominal figures, the cases
held and each case's row, and the judgement; ``--markdown`` writes the same as tables.

    .venv/bin/python benchmarks/machine_seeds.py --machine compact --seeds 0 1 2 --out runs/compact-seeds \\
        --json benchmarks/results/machines/compact_seeds.json --markdown benchmarks/results/machines/compact_seeds.md
    .venv/bin/python benchmarks/machine_seeds.py --machine compact --adapt-from komodo --seeds 0 1 2 \\
        --out runs/compact-from-komodo --json benchmarks/results/machines/compact_from_komodo.json
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

from autoscoop.core.safe_files import read_yaml, write_json_atomically, write_text_atomically

FILL_BAR, SUCCESS_BAR = 0.70, 0.95
"""The trained policy's nominal bars: fill factor of the rated load, and success."""


def autoscoop(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "autoscoop.cli", *args], check=True)


def train(machine: str, recipe: str, seed: int, run: Path, extra: list[str]) -> None:
    """Train one seed, or continue it where a run directory was cut: in training, or finished but cut while its
    recipe's selection validated the snapshots (no selection.json yet); a finished and chosen one is kept."""
    info = run / "run.json"
    if info.is_file():
        finished = json.loads(info.read_text()).get("status") == "finished"
        choosing = "selection" in read_yaml(run / "hyperparams.yaml", "hyperparams") and not (run / "selection.json").is_file()
        if not finished or choosing:
            autoscoop("train", "--machine", machine, "--resume", str(run))
        return
    autoscoop("train", "--machine", machine, "--recipe", recipe, "--seed", str(seed), "--out", str(run),
              "--no-progress", *extra)


def adapt_from(machine: str, origin: str, seed: int, run: Path, extra: list[str]) -> None:
    """Warm-start one seed from ``origin``'s shipped controller, or continue a run that was cut (in training, or
    before its selection); a finished and chosen one is kept."""
    info = run / "run.json"
    if info.is_file():
        if json.loads(info.read_text()).get("status") != "finished" or not (run / "selection.json").is_file():
            autoscoop("adapt", "--machine", machine, "--resume", str(run), "--no-progress")
        return
    autoscoop("adapt", "--machine", machine, "--policy", "default", "--from-machine", origin, "--seed", str(seed),
              "--out", str(run), "--no-progress", *extra)


def stress(machine: str, policy: str, episodes: int, out: Path) -> dict:
    if not out.is_file():
        autoscoop("stress", "--machine", machine, "--policy", policy, "--episodes", str(episodes), "--json", str(out))
    return json.loads(out.read_text())


def summary_of(result: dict) -> dict:
    """Nominal figures, cases held, and each case's success, volumetric fill, fill, cycle and overload."""
    rows = {row["case"]: row for row in result["rows"]}
    nominal = rows["nominal"]["stats"]
    return {
        "policy": result["policy"], "episodes": result["episodes"],
        "nominal": {key: nominal[key] for key in ("fill_factor_mean", "fill_factor_std", "success_rate",
                                                  "cycle_time_mean", "cycle_time_std", "volumetric_fill_mean")},
        "cases_held": sum(row["passed"] for row in result["rows"]),
        "cases_failed": [row["case"] for row in result["rows"] if not row["passed"]],
        "cases": {case: {key: row["stats"][key] for key in ("success_rate", "volumetric_fill_mean", "fill_factor_mean",
                                                             "cycle_time_mean", "overload_rate", "physics_errors")}
                  for case, row in rows.items()},
    }


def judge(policy: dict, scripted: dict) -> dict:
    """Which of the four bars the policy meets against the scripted scoop's figures."""
    nominal, bar_cycle = policy["nominal"], scripted["nominal"]["cycle_time_mean"]
    bars = {
        f"fill >= {FILL_BAR}": nominal["fill_factor_mean"] >= FILL_BAR,
        f"success >= {SUCCESS_BAR}": nominal["success_rate"] >= SUCCESS_BAR,
        f"cycle <= scripted {bar_cycle:.2f} s": (nominal["cycle_time_mean"] or float("inf")) <= bar_cycle,
        f"cases held >= scripted {scripted['cases_held']}": policy["cases_held"] >= scripted["cases_held"],
    }
    return {"bars": bars, "passed": all(bars.values())}


def markdown(machine: str, rows: list[dict]) -> str:
    lines = [f"# {machine}: trained seeds against the scripted scoop", "",
             "| policy | nominal fill | success | cycle (s) | cases held | not held | bars |", "|---|--:|--:|--:|--:|---|---|"]
    for row in rows:
        n = row["nominal"]
        verdict = "" if "judgement" not in row else ("all" if row["judgement"]["passed"] else "short: " + "; ".join(
            bar for bar, ok in row["judgement"]["bars"].items() if not ok))
        lines.append(f"| {row['policy']} | {n['fill_factor_mean']:.3f} ± {n['fill_factor_std']:.3f} | "
                     f"{n['success_rate']:.2f} | {n['cycle_time_mean']:.2f} ± {n['cycle_time_std']:.2f} | "
                     f"{row['cases_held']} of 11 | {', '.join(row['cases_failed']) or '-'} | {verdict} |")
    cases = list(rows[0]["cases"])
    lines += ["", "Success / volumetric fill / overload per case:", "",
              "| case | " + " | ".join(row["policy"] for row in rows) + " |", "|---|" + "--:|" * len(rows)]
    for case in cases:
        cells = [f"{r['cases'][case]['success_rate']:.2f} / {r['cases'][case]['volumetric_fill_mean']:.2f} / "
                 f"{r['cases'][case]['overload_rate']:.2f}" for r in rows]
        lines.append(f"| {case} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--machine", required=True, metavar="NAME|DIR")
    parser.add_argument("--recipe", default="robot")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--episodes", type=int, default=100, help="stress episodes per case (default 100)")
    parser.add_argument("--train-args", default="", help="more options for train (or adapt), one string")
    parser.add_argument("--adapt-from", metavar="MACHINE",
                        help="warm-start each seed from this machine's shipped controller (autoscoop adapt "
                             "--from-machine) instead of training it")
    parser.add_argument("--out", type=Path, required=True, metavar="DIR")
    parser.add_argument("--json", type=Path, required=True, metavar="FILE")
    parser.add_argument("--markdown", type=Path, metavar="FILE")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    scripted = summary_of(stress(args.machine, "heuristic", args.episodes, args.out / "stress-heuristic.json"))
    rows = [scripted]
    for seed in args.seeds:
        run = args.out / f"{Path(args.machine).name}-s{seed}"
        if args.adapt_from:
            adapt_from(args.machine, args.adapt_from, seed, run, args.train_args.split())
        else:
            train(args.machine, args.recipe, seed, run, args.train_args.split())
        row = summary_of(stress(args.machine, str(run), args.episodes, args.out / f"stress-s{seed}.json"))
        row["seed"] = seed
        row["judgement"] = judge(row, scripted)
        rows.append(row)
    write_json_atomically(args.json, {"machine": args.machine, "recipe": None if args.adapt_from else args.recipe,
                                      "train_args": args.train_args,
                                      "adapt_from": args.adapt_from,
                                      "seeds": args.seeds, "stress_episodes": args.episodes, "rows": rows,
                                      "seeds_passing": sum(r["judgement"]["passed"] for r in rows[1:])})
    if args.markdown:
        write_text_atomically(args.markdown, markdown(Path(args.machine).name, rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
