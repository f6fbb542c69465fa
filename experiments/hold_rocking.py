"""Does the loaded loader come to rest? Scripted scoops, then 5 s held still; motion over the last second.

After each scripted episode the commands go to zero (wheels stopped, servo setpoints held) for 5 s. Over
the last second it reports the cutting edge's height peak to peak (mm) and the chassis pitch rate
(rad/s, rms); a physics step or contact stiffness that lets the loaded loader keep rocking on its
wheels shows as a pitch rate well above the few mrad/s of a resting loader.

    .venv/bin/python experiments/hold_rocking.py --episodes 10
    .venv/bin/python experiments/hold_rocking.py --episodes 10 --set env.timestep_s=0.025 --set pile.rolling=false \
        --contact-time-constant 0.0417
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

ROCKING_RADPS = 0.03
"""Chassis pitch rate (rms over the last second) above which a hold counts as rocking, rad/s."""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--hold-s", type=float, default=5.0)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--contact-time-constant", type=float, default=0.0, metavar="S",
                        help="replace max(0.02, 2 x step) and turn MuJoCo's refsafe floor off")
    args = parser.parse_args()

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
    if args.contact_time_constant:
        sim.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_REFSAFE)
    controller = heuristic_for(config)
    pitch_dof = sim.model.joint("root").dofadr[0] + 4  # angular velocity about the chassis y axis
    tip_p2p, pitch_rms = [], []
    for episode in range(args.seed, args.seed + args.episodes):
        rollout(controller, env, episode)
        samples: list[tuple[float, float]] = []

        def sample(samples: list[tuple[float, float]] = samples) -> None:
            samples.append((sim.tip_world[2], sim.data.qvel[pitch_dof]))

        sim.command(0.0, 0.0, 0.0)
        sim.add_substep_observer(sample)
        sim.step(int(round(args.hold_s / sim.model.opt.timestep)))
        sim.remove_substep_observer(sample)
        last = np.array(samples[-int(round(1.0 / sim.model.opt.timestep)):])
        tip_p2p.append(1000.0 * float(np.ptp(last[:, 0])))
        pitch_rms.append(float(np.sqrt(np.mean(last[:, 1] ** 2))))
    rocking = sum(rate > ROCKING_RADPS for rate in pitch_rms)
    print("tip height peak to peak over the last second, mm:", np.round(tip_p2p, 2).tolist())
    print("chassis pitch rate rms over the last second, rad/s:", np.round(pitch_rms, 4).tolist())
    print(f"rocking (pitch rate > {ROCKING_RADPS} rad/s): {rocking} of {args.episodes} holds")
    return 0


if __name__ == "__main__":
    sys.exit(main())
