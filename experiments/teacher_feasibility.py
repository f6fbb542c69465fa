"""Can an actor that sees the drawn world hold heavy earth and the randomised world at once?

The deployable actor reads the robot's state only and cuts one volume for every earth
(docs/experiments/history.md). A teacher for teacher-student training would read, beside it, what the
critic already reads (:mod:`autoscoop.envs.privileged`: the true load and volume in the bucket, the particle
mass, the link's delay). This trains such a teacher with the usual command and recipe, the paper's policy
swapped for one whose actor reads the critic's input (``train``), then runs its kept model over stress
cases in the privileged environment (``evaluate``). The teacher is not deployable: it keeps
only the SB3 model (``policy.zip``, the best periodic evaluation's), no safe actor file, so the recipe's
selection has nothing to rank and the export fails after training, by design of this probe.

    .venv/bin/python experiments/teacher_feasibility.py train --recipe robot_history --seed 10 --n-envs 2 \
        --episodes 4000 --set reward.overload_from=1.0 --set reward.c_overload_step=20 --out runs/teacher-s10
    .venv/bin/python experiments/teacher_feasibility.py evaluate runs/teacher-s10 --episodes 100 \
        --cases nominal,light,heavy,randomized --json out/teacher_cases.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from autoscoop.agents import sb3_policies
from autoscoop.agents.loading import SB3Policy
from autoscoop.agents.sb3_policies import PrivilegedState, is_privileged
from autoscoop.core.config import ScoopConfig
from autoscoop.core.safe_files import write_json_atomically
from autoscoop.envs.rollout import rollout
from autoscoop.evaluation.stress import row_from_outcomes, select_cases


class TeacherPolicy(sb3_policies.PaperPolicy):
    """The paper's policy whose actor reads what the critic reads: the actor's input and the privileged numbers."""

    def actor_features(self, features_extractor: Any) -> Any:
        if is_privileged(self.observation_space, self.history_steps):
            return PrivilegedState(self.observation_space, self.history_steps)
        return features_extractor


def train(argv: list[str]) -> int:
    from autoscoop.cli import main as cli_main  # noqa: PLC0415
    from autoscoop.training import callbacks  # noqa: PLC0415

    sb3_policies.PaperPolicy = TeacherPolicy  # the training factory builds the paper's policy by this name
    callbacks.save_safe_actor = lambda *args, **kwargs: None  # the safe actor file holds robot-state actors only
    return cli_main(["train", *argv])


def evaluate(argv: list[str]) -> int:
    from stable_baselines3 import DDPG  # noqa: PLC0415

    from autoscoop.training.checkpoints import read_run_json, read_run_yaml  # noqa: PLC0415
    from autoscoop.training.factories import make_training_env  # noqa: PLC0415

    parser = argparse.ArgumentParser(prog="teacher_feasibility.py evaluate")
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cases", default="nominal,light,heavy,randomized")
    parser.add_argument("--json", type=Path, default=None, help="write each case's figures here")
    args = parser.parse_args(argv)
    results = {}
    history = int((read_run_yaml(args.run_dir, "hyperparams.yaml") or {}).get("history_steps", 1))
    frame = read_run_json(args.run_dir).get("state_frame", "chassis")  # the frame the actor was trained in
    for case in select_cases(args.cases):
        config = case.config(ScoopConfig())
        env = make_training_env(config, privileged=True, history=history)
        model = DDPG(TeacherPolicy, env, policy_kwargs={"history_steps": history}, device="cpu")
        model.set_parameters(str(args.run_dir / "policy.zip"), device="cpu")
        teacher = SB3Policy(model, "teacher")
        teacher.state_frame = frame  # rollout builds the state in the frame a policy declares
        outcomes = [rollout(teacher, env, args.seed + i) for i in range(args.episodes)]
        env.close()
        row = row_from_outcomes(case, outcomes)
        s = row.stats
        particles = float(np.mean([o.particles for o in outcomes]))
        results[case.name] = {key: s[key] for key in ("success_rate", "fill_factor_mean", "volumetric_fill_mean",
                                                      "overload_rate", "cycle_time_mean")} | {
            "particles_mean": particles, "particles_std": float(np.std([o.particles for o in outcomes])),
            "passed": row.passed}
        print(f"{case.name}: success {s['success_rate']:.2f}, fill {s['fill_factor_mean']:.3f}, volumetric "
              f"{s['volumetric_fill_mean']:.2f}, overload {s['overload_rate']:.2f}, cycle {s['cycle_time_mean']:.2f} s, "
              f"particles {particles:.1f} ± {results[case.name]['particles_std']:.1f} ({'holds' if row.passed else 'fails'})", flush=True)
    if args.json:
        write_json_atomically(args.json, {"run": str(args.run_dir), "model": "policy.zip (the best periodic evaluation's)",
                                          "episodes": args.episodes, "seed": args.seed, "cases": results})
    return 0


def main() -> int:
    if len(sys.argv) < 2 or sys.argv[1] not in ("train", "evaluate"):
        print(__doc__)
        return 2
    return train(sys.argv[2:]) if sys.argv[1] == "train" else evaluate(sys.argv[2:])


if __name__ == "__main__":
    raise SystemExit(main())
