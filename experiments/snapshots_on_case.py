"""Each validated snapshot of a run on chosen stress cases, with more episodes than the validation suite.

The recipe's validation suite (``selection.json``) runs each candidate 20 episodes per case. This runs
every candidate it names again on the given cases (default: heavy), ``--episodes`` each from seed
``--seed`` (1000: apart from the validation's 20000 on and the reports' 0-99), and prints, per
candidate, its validation success and shortfall beside success / volumetric fill / overload per case:
whether any snapshot of the run holds a case, or the choice among them cannot help.

    .venv/bin/python experiments/snapshots_on_case.py runs/RUN --cases heavy --episodes 40
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from autoscoop.core.config import ScoopConfig
from autoscoop.evaluation.stress import row_from_outcomes, run_case, select_cases


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir", type=Path, help="a training run with a selection.json")
    parser.add_argument("--cases", default="heavy", help="stress cases, comma-separated (default heavy)")
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--seed", type=int, default=1000)
    args = parser.parse_args()
    selection = args.run_dir / "selection.json"
    if not selection.is_file():
        parser.error(f"{selection} not found: the run has made no validated choice")
    cases = select_cases(args.cases)
    for candidate in json.loads(selection.read_text())["candidates"]:
        cells = []
        for case in cases:
            stats = row_from_outcomes(case, run_case(candidate["path"], ScoopConfig(), case, args.episodes,
                                                     seed=args.seed, progress=False)).stats
            cells.append(f"{case.name}: {stats['success_rate']:.2f} / {stats['volumetric_fill_mean']:.2f} / "
                         f"{stats['overload_rate']:.2f}")
        validated = candidate["by_case"].get(cases[0].name, {}).get("success_rate")
        print(f"{candidate['name']}: validation {cases[0].name} success {validated}, shortfall "
              f"{candidate['shortfall']}; {'; '.join(cells)}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
