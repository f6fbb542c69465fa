"""Measure ``autoscoop sweep`` against the same trials run one after another (the sweep's acceptance).

``.venv/bin/python experiments/sweep_acceptance.py WORK_DIR`` runs the sweep of ``space.yaml`` (4 trials x
300 episodes, embedded Ray, 2 CPUs), kill -9s its driver once a trial has finished and another has a checkpoint
at episode 100 or later, resumes it with ``--resume``, then trains the same 4 trials (settings and seeds from
``sweep.csv``) one after another with ``autoscoop train``. It writes ``measure.json`` (wall times, what was
killed and resumed, the load) into WORK_DIR and copies the sweep's table, report, figure and JSON beside itself.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1] / "benchmarks" / "results" / "sweep"
"""Where the space file lies and the results go."""
BIN = Path(sys.executable).parent
EPISODES, TRIALS = 300, 4
TRAIN = ["--eval-every", "50", "--eval-episodes", "10", "--checkpoint-every", "50", "--no-progress"]


def status(run_dir: Path) -> str | None:
    try:
        return json.loads((run_dir / "run.json").read_text()).get("status")
    except (OSError, ValueError):
        return None


def checkpointed(run_dir: Path) -> int:
    try:
        return json.loads((run_dir / "checkpoint" / "state.json").read_text())["episodes_done"]
    except (OSError, ValueError, KeyError):
        return 0


def snapshot(run_dir: Path) -> dict[str, int]:
    return {str(p.relative_to(run_dir)): p.stat().st_mtime_ns for p in sorted(run_dir.rglob("*"))
            if p.is_file() and "tb" not in p.parts}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("work", type=Path)
    work = parser.parse_args().work.resolve()
    out = work / "sweep"
    work.mkdir(parents=True, exist_ok=True)
    sweep = [str(BIN / "autoscoop"), "sweep", "--num-cpus", "2", "--json", str(work / "sweep.json")]
    first = [*sweep, "--out", str(out), "--space", str(HERE / "space.yaml"), "--trials", str(TRIALS),
             "--episodes", str(EPISODES)]
    resume = [*sweep, "--resume", str(out)]
    facts: dict = {"commands": {"sweep": " ".join(first), "resume": " ".join(resume)},
                   "cpu_count": os.cpu_count(), "load": []}
    start = time.time()
    runs: list[Path] = []
    finished: list[Path] = []
    with open(work / "driver1.log", "w") as log:
        driver = subprocess.Popen(first, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        while driver.poll() is None:
            runs = sorted((out / "runs").glob("*")) if (out / "runs").is_dir() else []
            finished = [d for d in runs if status(d) == "finished"]
            going = [d for d in runs if status(d) == "running" and checkpointed(d) >= 100]
            if int(time.time() - start) % 60 == 0:
                facts["load"].append([round(time.time() - start), os.getloadavg()[0]])
            if finished and going:
                break
            time.sleep(1)
        killed_at = time.time() - start
        if driver.poll() is not None:
            raise SystemExit(f"the sweep ended (status {driver.returncode}) before it could be killed midway")
        os.kill(driver.pid, signal.SIGKILL)
        driver.wait()
    time.sleep(2)
    try:  # the killed embedded Ray's two idle agents share the driver's process group
        os.killpg(driver.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    facts["killed_at_s"] = round(killed_at, 1)
    facts["finished_at_kill"] = [d.name for d in finished]
    facts["interrupted_at_kill"] = {d.name: {"status": status(d), "checkpoint_episode": checkpointed(d)}
                                    for d in runs if status(d) != "finished"}
    before = {d.name: snapshot(d) for d in finished}
    resume_start = time.time()
    with open(work / "driver2.log", "w") as log:
        subprocess.run(resume, stdout=log, stderr=subprocess.STDOUT, check=True)
    facts["resume_s"] = round(time.time() - resume_start, 1)
    facts["sweep_wall_s"] = round(killed_at + facts["resume_s"], 1)
    facts["finished_trials_untouched"] = {name: snapshot(out / "runs" / name) == files for name, files in before.items()}
    rows = list(csv.DictReader(open(out / "sweep.csv")))
    sequential = []
    seq_start = time.time()
    for row in rows:
        t0 = time.time()
        run_dir = work / "sequential" / row["trial_id"]
        command = [str(BIN / "autoscoop"), "train", "--recipe", "paper", "--episodes", str(EPISODES), "--seed", row["seed"],
                   "--set", f"reward.c_w={row['reward.c_w']}", "--hyper",
                   f"hyperparams.learning_rate={row['hyperparams.learning_rate']}", *TRAIN, "--out", str(run_dir)]
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        info = json.loads((run_dir / "run.json").read_text())
        sequential.append({"trial_id": row["trial_id"], "command": " ".join(command), "wall_s": round(time.time() - t0, 1),
                           "train_wall_s": info["wall_s"], "best_score": info.get("best_score"),
                           "sweep_score": float(row["score"])})
    facts["sequential"] = sequential
    facts["sequential_wall_s"] = round(time.time() - seq_start, 1)
    facts["load"].append(["end", os.getloadavg()[0]])
    (work / "measure.json").write_text(json.dumps(facts, indent=2) + "\n")
    for name in ("sweep.csv", "report.md", "sweep.png"):
        shutil.copyfile(out / name, HERE / name)
    shutil.copyfile(work / "sweep.json", HERE / "sweep.json")
    shutil.copyfile(work / "measure.json", HERE / "measure.json")
    print(json.dumps(facts, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
