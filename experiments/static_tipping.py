"""Does a load in the bucket tip the loader forward when it stands still? (heavy earth)

The loader stands on flat ground away from the pile, arm and bucket held by their servos at a lift
angle (rad, positive lowers the arm: 0.23 is the start, -0.10 the highest) and a tilt angle (rad,
negative curls the bucket back), and a payload (kg) is added to the bucket body's mass at its centre
of mass. After 2 s (96 physics steps) the script prints the chassis pitch (deg, positive nose down, as
the IMU reports it: ``sim/load_cell.py``) and the tip's height (m) per payload.

    .venv/bin/python experiments/static_tipping.py > benchmarks/results/experiments/static_tipping.txt
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from autoscoop.core.config import ScoopConfig
from autoscoop.sim.load_cell import chassis_pitch_rad
from autoscoop.sim.scene import ScoopSim

PAYLOADS_KG = (0, 4, 5, 6, 7, 8)
POSES_RAD = [(lift, tilt) for lift in (0.23, 0.10, -0.10) for tilt in (0.0, -0.5)]
CHASSIS_X_M = -2.5
"""Far behind the pile (its toe is ahead of the origin): nothing but the ground touches the loader."""


def main() -> None:
    sim = ScoopSim(ScoopConfig())
    sim.reset(np.random.default_rng(0))
    model, data = sim.model, sim.data
    bucket = model.body("bucket").id
    mass, inertia = float(model.body_mass[bucket]), model.body_inertia[bucket].copy()
    start = (data.qpos.copy(), data.act.copy())
    print("lift_rad tilt_rad " + " ".join(f"{kg}kg:pitch_deg/tip_z_m" for kg in PAYLOADS_KG))
    for lift, tilt in POSES_RAD:
        cells = []
        for payload in PAYLOADS_KG:
            data.qpos[:], data.act[:] = start
            data.qvel[:] = 0.0
            sim.set_pose(CHASSIS_X_M, lift, tilt)
            model.body_mass[bucket] = mass + payload
            model.body_inertia[bucket] = inertia * (1.0 + payload / mass)
            sim.command(0.0, 0.0, 0.0)
            mujoco.mj_forward(model, data)
            sim.step(96)
            cells.append(f"{math.degrees(chassis_pitch_rad(sim)):5.1f}/{sim.tip_world[2]:.2f}")
        print(f"{lift:5.2f} {tilt:5.2f} " + " ".join(cells))


if __name__ == "__main__":
    main()
