"""Does ``--n-envs`` pay on this machine? Env steps/s, training wall time and policy quality with 1 and N envs.

Three measurements, one after another (never two at once: they share the cores):

1. ``autoscoop bench --n-envs N``: aggregate environment steps per second with one environment
   (``DummyVecEnv``) and with N in subprocesses (``SubprocVecEnv``, as training builds them), and the ratio;
2. ``autoscoop train --recipe paper --n-envs K --seed SEED --episodes E`` for K = 1 and N and each seed: the wall time
   (outside, around the process, seconds; and the run's own ``wall_s`` in ``run.json``) and the environment
   steps it took (``episodes.csv``), hence training's env steps per wall second;
3. ``autoscoop eval --policy RUN_DIR --episodes 50`` (nominal world) of each run's kept policy: fill factor
   mean ± std and success rate, since more environments change the learning (SB3 takes one gradient step per
   vector step, so with N environments there are 1/N as many updates per transition).

Writes ``OUT/bench.json`` (the bench's JSON), ``OUT/train_nK_sSEED.json`` (wall times, the run's record,
the evaluation summary) and ``OUT/summary.json`` (the figures side by side, with means over the seeds).
Run directories ``neK_sSEED`` go under ``--runs`` (default a temporary folder); ``--reuse`` keeps a finished
run directory there instead of training again (the process wall time then comes from a ``neK_sSEED.wall``
file beside it, if any) and its ``neK_sSEED.eval.json`` if present.

    .venv/bin/python benchmarks/n_envs_scaling.py --out benchmarks/results/n_envs --runs /tmp/n_envs_runs
"""

from __future__ import annotations

import argparse
import csv
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

CLI = [sys.executable, "-m", "autoscoop.cli"]


def timed(command: list[str], log: Path) -> float:
    """Run ``command`` (output to ``log``), fail loudly on a non-zero exit; its wall time in seconds."""
    start = time.perf_counter()
    with open(log, "w") as out:
        code = subprocess.call(command, stdout=out, stderr=subprocess.STDOUT)
    wall = time.perf_counter() - start
    if code != 0:
        raise SystemExit(f"{' '.join(command)} exited {code}; see {log}")
    return wall


def train(run_dir: Path, n_envs: int, seed: int, episodes: int, reuse: bool) -> float | None:
    """Train (or, with ``reuse``, keep a finished) run; the process's wall time in seconds (``None``: unknown)."""
    record = run_dir / "run.json"
    if reuse and record.exists() and json.loads(record.read_text()).get("status") == "finished":
        wall_file = run_dir.parent / f"{run_dir.name}.wall"
        return float(wall_file.read_text()) if wall_file.exists() else None
    command = [*CLI, "train", "--recipe", "paper", "--n-envs", str(n_envs), "--seed", str(seed), "--episodes", str(episodes),
               "--no-progress", "--out", str(run_dir)]
    wall = timed(command, run_dir.parent / f"{run_dir.name}.train.log")
    (run_dir.parent / f"{run_dir.name}.wall").write_text(f"{wall:.1f}\n")
    return wall


def evaluate(run_dir: Path, episodes: int, reuse: bool) -> dict[str, Any]:
    """``autoscoop eval`` of the run's kept policy, nominal world: its JSON summary."""
    out = run_dir.parent / f"{run_dir.name}.eval.json"
    if reuse and out.exists():
        return json.loads(out.read_text())
    timed([*CLI, "eval", "--policy", str(run_dir), "--episodes", str(episodes), "--json", str(out),
           "--allow-empty"],  # a run that learnt nothing is a figure here too
          run_dir.parent / f"{run_dir.name}.eval.log")
    return json.loads(out.read_text())


def training_steps(run_dir: Path) -> int:
    """Environment steps the run took, all environments together (the ``steps`` column of ``episodes.csv``)."""
    with open(run_dir / "episodes.csv", newline="") as rows:
        return sum(int(row["steps"]) for row in csv.DictReader(rows))


def mean_std(values: list[float]) -> dict[str, float]:
    """Mean and sample standard deviation (0 for one value) of ``values``."""
    return {"mean": statistics.fmean(values), "std": statistics.stdev(values) if len(values) > 1 else 0.0}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n-envs", type=int, default=2, help="environments to compare with one (default 2)")
    parser.add_argument("--episodes", type=int, default=800, help="training episodes per run (default 800)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0], help="training seeds, each with 1 and N envs")
    parser.add_argument("--eval-episodes", type=int, default=50, help="evaluation episodes per policy (default 50)")
    parser.add_argument("--bench-steps", type=int, default=2000, help="bench: steps per environment and repeat")
    parser.add_argument("--bench-repeats", type=int, default=5, help="bench: repeats (the median is reported)")
    parser.add_argument("--runs", type=Path, help="folder for the run directories (default: a new temporary one)")
    parser.add_argument("--reuse", action="store_true", help="keep finished run directories found under --runs")
    parser.add_argument("--skip-bench", action="store_true", help="keep OUT/bench.json as it is")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/n_envs"))
    args = parser.parse_args()
    runs = args.runs or Path(tempfile.mkdtemp(prefix="n_envs_"))
    runs.mkdir(parents=True, exist_ok=True)
    args.out.mkdir(parents=True, exist_ok=True)
    if not args.skip_bench:
        timed([*CLI, "bench", "--n-envs", str(args.n_envs), "--steps", str(args.bench_steps),
               "--repeats", str(args.bench_repeats), "--json", str(args.out / "bench.json")], runs / "bench.log")
    bench = json.loads((args.out / "bench.json").read_text())
    summary: dict[str, Any] = {
        "env_steps_per_s_1": bench["env_steps_per_s_1"], f"env_steps_per_s_{args.n_envs}": bench["env_steps_per_s_n"],
        "scaling_ratio": bench["scaling_ratio"], "cpu": bench["cpu"], "cpu_count": bench["cpu_count"], "training": {},
    }
    for n_envs in (1, args.n_envs):
        rows = []
        for seed in args.seeds:
            run_dir = runs / f"ne{n_envs}_s{seed}"
            wall = train(run_dir, n_envs, seed, args.episodes, args.reuse)
            record = json.loads((run_dir / "run.json").read_text())
            result = evaluate(run_dir, args.eval_episodes, args.reuse)
            quality = {key: result[key] for key in ("fill_factor_mean", "fill_factor_std", "success_rate",
                                                    "cycle_time_mean", "cycle_time_std")}
            steps = training_steps(run_dir)
            entry = {"n_envs": n_envs, "seed": seed, "episodes": args.episodes, "process_wall_s": wall,
                     "run_wall_s": record.get("wall_s"), "env_steps": steps,
                     "env_steps_per_s": steps / record["wall_s"] if record.get("wall_s") else None,
                     "best_episode": record.get("best_episode"), "best_score": record.get("best_score"),
                     "eval_episodes": args.eval_episodes, **quality, "run": record,
                     "eval": {key: value for key, value in result.items() if key not in ("episodes_detail", "config")}}
            (args.out / f"train_n{n_envs}_s{seed}.json").write_text(json.dumps(entry, indent=2) + "\n")
            rows.append({key: entry[key] for key in entry if key not in ("run", "eval")})
            print(f"n_envs {n_envs} seed {seed}: {record.get('wall_s')} s, fill {quality['fill_factor_mean']:.3f}, "
                  f"success {quality['success_rate']:.2f}", flush=True)
        summary["training"][f"n{n_envs}"] = {
            "runs": rows, **{key: mean_std([row[key] for row in rows])
                             for key in ("run_wall_s", "env_steps_per_s", "fill_factor_mean", "success_rate")}}
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
