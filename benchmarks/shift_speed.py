"""How long a loader's shift takes to simulate: wall-clock seconds of a 15-cycle shift on one core.

Runs ``autoscoop shift``'s loop (:func:`autoscoop.evaluation.shift.run_shift`) for ``--policy`` on the default shift
pile, pinned to one CPU core with one math thread, and prints (or writes, ``--json``) the wall-clock time of the
whole shift (the pile's settling included, the policy's loading not), the time of each cycle, the simulated shift
time and their ratio.

    .venv/bin/python benchmarks/shift_speed.py
    .venv/bin/python benchmarks/shift_speed.py --policy default --cycles 15 --json benchmarks/results/speed/shift_default.json
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

for _name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ.setdefault(_name, "1")  # before numpy or torch start their thread pools


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", default="default", help="heuristic, default or a policy file (default default)")
    parser.add_argument("--cycles", type=int, default=15, help="loading cycles (default 15)")
    parser.add_argument("--seed", type=int, default=0, help="the shift's seed (default 0)")
    parser.add_argument("--core", type=int, default=None, help="CPU core to pin to (default: the first allowed)")
    parser.add_argument("--json", type=Path, help="write the timings to this JSON file")
    args = parser.parse_args(argv)
    if args.cycles < 1:
        parser.error("--cycles must be 1 or more")

    allowed = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    core = args.core if args.core is not None else (allowed[0] if allowed else None)
    if core is not None:
        os.sched_setaffinity(0, {core})

    import torch  # noqa: PLC0415

    from autoscoop.agents.loading import load_policy  # noqa: PLC0415
    from autoscoop.core.config import ScoopConfig  # noqa: PLC0415
    from autoscoop.core.safe_files import write_json_atomically  # noqa: PLC0415
    from autoscoop.evaluation.shift import run_shift  # noqa: PLC0415

    torch.set_num_threads(1)
    config = ScoopConfig()
    policy = load_policy(args.policy, config)
    cycle_ends: list[float] = []
    started = time.perf_counter()
    result = run_shift(policy, config, args.cycles, seed=args.seed, progress=False,
                       after_cycle=lambda row: cycle_ends.append(time.perf_counter()))
    wall_s = time.perf_counter() - started
    marks = [started, *cycle_ends]
    simulated_s = result["totals"]["shift_time_s"]
    out = {
        "policy": args.policy,
        "cycles": len(result["cycles"]),
        "seed": args.seed,
        "pile_particles": config.shift.pile_particles,
        "wall_s": wall_s,
        "cycle_wall_s": [b - a for a, b in zip(marks, marks[1:], strict=False)],
        "simulated_shift_s": simulated_s,
        "simulated_per_wall": simulated_s / wall_s,
        "core": core,
        "python": platform.python_version(),
        "machine": platform.machine(),
        "processor_count": os.cpu_count(),
        "command": " ".join([Path(sys.argv[0]).name, *(argv if argv is not None else sys.argv[1:])]),
    }
    print(f"{args.policy}: {out['cycles']} cycles in {wall_s:.1f} s wall ({simulated_s:.0f} s simulated, "
          f"{out['simulated_per_wall']:.0f}x real time) on core {core}")
    if args.json:
        write_json_atomically(args.json, out)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
