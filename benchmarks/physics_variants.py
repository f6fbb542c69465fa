"""What a change of the physics does to speed and to the scripted scoop: the figures behind docs/performance.md.

Runs the scripted controller for ``--episodes`` episodes (seeds from ``--seed``) on the default pile with
config overrides (``--set pile.rolling=false``), MuJoCo option edits applied after compiling
(``--option iterations=6``, ``--option solver=CG``, ``--option disable=WARMSTART``) and, if given, a
contact time constant that replaces max(0.02, 2 x step) (``--contact-time-constant 0.0417``; MuJoCo's
``refsafe`` floor of two steps is then turned off). Prints the fill factor (mean +- std), success,
cycle time and physics errors (wall-clock speed: ``autoscoop bench --set ...``). With
``--instructions`` it runs itself twice under ``valgrind --tool=callgrind`` (settling the pile
variants only, then settling plus the episodes) and reports the instructions
spent in ``mj_step`` per simulated second of the episodes: a cost that does not vary with the
machine's speed.

    .venv/bin/python benchmarks/physics_variants.py --episodes 6 --instructions
    .venv/bin/python benchmarks/physics_variants.py --episodes 6 --instructions --set pile.rolling=false
    .venv/bin/python benchmarks/physics_variants.py --episodes 10 --option iterations=6
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np


def apply_options(model, options: list[str]) -> None:
    """Edit ``model.opt`` from ``key=value`` strings (solver, cone, integrator, disable, integers, floats)."""
    import mujoco  # noqa: PLC0415

    enums = {"solver": (mujoco.mjtSolver, "mjSOL_"), "cone": (mujoco.mjtCone, "mjCONE_"),
             "integrator": (mujoco.mjtIntegrator, "mjINT_")}
    for item in options:
        key, _, value = item.partition("=")
        if key in enums:
            enum, prefix = enums[key]
            setattr(model.opt, key, getattr(enum, prefix + value.upper()))
        elif key == "disable":
            model.opt.disableflags |= int(getattr(mujoco.mjtDisableBit, "mjDSBL_" + value.upper()))
        elif key in ("iterations", "ls_iterations"):
            setattr(model.opt, key, int(value))
        elif key in ("tolerance", "sleep_tolerance", "impratio"):
            setattr(model.opt, key, float(value))
        else:
            raise SystemExit(f"--option {item}: unknown key {key!r}")


def run(args: argparse.Namespace) -> dict:
    import mujoco  # noqa: PLC0415

    import autoscoop.sim.scene as scene  # noqa: PLC0415
    from autoscoop.agents.loading import heuristic_for  # noqa: PLC0415
    from autoscoop.core.config import ScoopConfig, parse_set_args  # noqa: PLC0415
    from autoscoop.envs.rollout import rollout  # noqa: PLC0415
    from autoscoop.envs.scoop import make_scoop_env  # noqa: PLC0415

    if args.contact_time_constant:
        scene.contact_time_constant_s = lambda _timestep: args.contact_time_constant
    config = ScoopConfig().with_overrides(parse_set_args(args.overrides))
    env = make_scoop_env(config)
    sim = env.unwrapped.sim
    apply_options(sim.model, args.option)
    if args.contact_time_constant:
        sim.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_REFSAFE)
    controller = heuristic_for(config)
    for i in range(args.episodes):  # settle the variants these seeds use
        env.reset(seed=args.seed + i)
    if os.environ.get("PHYSICS_VARIANTS_SETTLE_ONLY"):
        return {}
    fills, successes, cycles, errors, simulated = [], [], [], 0, 0.0
    elapsed = {"s": 0.0}

    def note_time(step: int, obs: np.ndarray, action: np.ndarray, reward: float, info: dict) -> None:
        elapsed["s"] = info["elapsed_s"]

    for i in range(args.episodes):
        outcome = rollout(controller, env, args.seed + i, observers=(note_time,))
        simulated += elapsed["s"]
        fills.append(outcome.fill_factor)
        successes.append(outcome.success)
        errors += int(outcome.physics_error)
        if outcome.success:
            cycles.append(outcome.cycle_time_s)
    return {"episodes": args.episodes, "seed": args.seed, "set": args.overrides, "option": args.option,
            "contact_time_constant_s": args.contact_time_constant,
            "fill_factor_mean": float(np.mean(fills)), "fill_factor_std": float(np.std(fills)),
            "success_rate": float(np.mean(successes)), "cycle_time_mean": float(np.mean(cycles)) if cycles else None,
            "physics_errors": errors, "simulated_s": simulated}


def count_instructions(argv: list[str]) -> dict:
    """Run this script under callgrind twice; instructions in ``mj_step`` per simulated second of the episodes."""
    inner = [a for a in argv if a != "--instructions"]
    counts, result = [], None
    for settle_only in (True, False):
        with tempfile.TemporaryDirectory() as tmp:
            env = {**os.environ, "PHYSICS_VARIANTS_SETTLE_ONLY": "1" if settle_only else ""}
            done = subprocess.run(["valgrind", "--tool=callgrind", "--collect-atstart=no", "--toggle-collect=mj_step",
                                   f"--callgrind-out-file={tmp}/out", sys.executable, __file__, *inner, "--json-line"],
                                  env=env, capture_output=True, text=True, check=True)
        counts.append(int(re.search(r"Collected : (\d+)", done.stderr).group(1)))
        lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
        result = json.loads(lines[-1]) if lines else result
    result["mj_step_instructions_per_simulated_s"] = (counts[1] - counts[0]) / result["simulated_s"]
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--option", action="append", default=[], metavar="KEY=VALUE", help="edit model.opt")
    parser.add_argument("--contact-time-constant", type=float, default=0.0, metavar="S")
    parser.add_argument("--instructions", action="store_true", help="count instructions under callgrind")
    parser.add_argument("--json", type=Path, metavar="FILE", help="also write the result here")
    parser.add_argument("--json-line", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    result = count_instructions(sys.argv[1:]) if args.instructions else run(args)
    print(json.dumps(result) if args.json_line else json.dumps(result, indent=1))
    if args.json:
        from autoscoop.core.safe_files import write_json_atomically  # noqa: PLC0415 - as the other imports, late

        write_json_atomically(args.json, result, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
