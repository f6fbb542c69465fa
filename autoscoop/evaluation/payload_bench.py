"""How well the joint torques tell the payload's mass: static holds and moving scoops (``autoscoop bench payload``).

Static holds: the loader stands still with its bucket raised (the carry pose of
:mod:`autoscoop.sim.capacity` and other raised poses); particles are dropped into the bucket one at a
time, and each time the bucket carries a new count (0 ... 25) the scene is left to settle, the
torques are averaged over :data:`AVERAGE_S`, and both estimators (paper eq. 4 and eq. 8) are compared
with the true mass. The true mass is that of every particle the bucket carries: inside the paper's
quadrilateral (docs/definitions.md's count) or heaped above its mouth, since the torques feel both; the error
against the quadrilateral's count alone is reported beside it.

Particles resting on a servo-held bucket need not come to rest in MuJoCo: with low bucket friction
and a coarse physics step they rattle in a limit cycle, and single torque readings then swing by
kilograms around the right mean. The bench waits up to :data:`MAX_SETTLE_S` for rest, averages over a
window long enough to span that rattle, and reports its size (``rattle_std_kg``: the standard
deviation of the instantaneous eq. 8 estimate over the window).

Moving scoops: the scripted baseline scoops the default pile; at every control step both estimators
read the torques (instantaneous, and averaged over the control period as the environment's load
cell does) and are compared with the true mass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from autoscoop.core import kinematics
from autoscoop.core import payload as payload_mod
from autoscoop.core.config import ScoopConfig
from autoscoop.core.state import STATE_SIZE
from autoscoop.core.version import __version__
from autoscoop.envs.records import EpisodeRecord
from autoscoop.sim.load_cell import ReadingWindow, instant_reading
from autoscoop.sim.scene import ScoopSim

HOLD_POSES_RAD: tuple[tuple[float, float], ...] = ((-0.10, -0.50), (0.0, -0.40), (-0.05, -0.30))
"""(lift, tilt) of the static holds: the carry pose (arm up, bucket fully curled) and two less curled."""
MAX_PARTICLES = 25
DROP_HEIGHT_M = 0.08
"""Height of each drop above the middle of the bucket's mouth, m."""
REST_SPEED_MPS = 0.005
"""The scene is at rest when no particle and no point of the arm moves faster than this, m/s."""
MAX_SETTLE_S = 4.0
"""Longest wait for rest after a drop, s (then the window average has to absorb the rattle)."""
AVERAGE_S = 2.0
"""Window over which the torques and angles of a static hold are averaged, s."""
SPARE_PARTICLES = 15
"""Drops allowed beyond the largest count, for those that bounce out."""
CARRIED_BOX_IN_BUCKET_M = ((-0.05, 0.30), (-0.12, 0.25))
"""(x, z) ranges in the bucket frame within which an off-ground particle rests on the bucket, m."""


@dataclass(frozen=True)
class HoldSample:
    """One static hold: readings averaged over the window, and the truth."""

    pose: int
    particles_carried: int
    particles_in_bucket: int
    mass_kg: float
    """mass of the particles the bucket carries (inside or heaped), kg."""
    mass_in_bucket_kg: float
    """mass of the particles inside the paper's quadrilateral (docs/definitions.md), kg."""
    lift_rad: float
    tilt_rad: float
    lift_torque_nm: float
    tilt_torque_nm: float
    chassis_pitch_rad: float
    settle_s: float
    at_rest: bool
    rattle_std_kg: float
    """standard deviation of the instantaneous eq. 8 estimate over the window, kg."""


def carried_particles(sim: ScoopSim) -> tuple[np.ndarray, np.ndarray]:
    """(inside, heaped) masks: inside the paper's quadrilateral; off the ground on or above the bucket, not inside."""
    local = sim.particles_in_bucket_frame()
    inside = kinematics.inside_bucket(local)
    (x_lo, x_hi), (z_lo, z_hi) = CARRIED_BOX_IN_BUCKET_M
    radius = sim.config.pile.radius_m
    near = ((local[:, 0] >= x_lo) & (local[:, 0] <= x_hi) & (local[:, 2] >= z_lo) & (local[:, 2] <= z_hi)
            & (np.abs(local[:, 1]) <= kinematics.BUCKET_INNER_HALF_WIDTH_M + radius))
    off_ground = sim.particle_positions[:, 2] > 1.5 * radius
    return inside, near & off_ground & ~inside


class _Hold:
    """A loader holding its bucket still at one pose, with particles parked out of the way."""

    def __init__(self, config: ScoopConfig, lift_rad: float, tilt_rad: float, n_particles: int) -> None:
        config = config.replace(pile=config.pile.replace(n_particles=n_particles, variants=1))
        self.sim = sim = ScoopSim(config)
        m, d = sim.model, sim.data
        m.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)  # teleported particles must wake
        mujoco.mj_resetData(m, d)
        sim.set_pose(-1.5, lift_rad, tilt_rad)
        for i in range(n_particles):
            sim.set_particle(i, np.array([2.0 + 0.1 * i, 3.0, config.pile.radius_m]))
        mujoco.mj_forward(m, d)
        self._particle_dofs = np.array([m.jnt_dofadr[m.joint(f"particle_{i:03d}").id] for i in range(n_particles)])
        self._arm_dofs = np.array([m.joint("lift").dofadr[0], m.joint("tilt").dofadr[0]])

    def speed(self) -> float:
        """Fastest particle (m/s) or arm point (joint rate x 0.9 m reach)."""
        qvel = self.sim.data.qvel
        particles = np.abs(qvel[self._particle_dofs[:, None] + np.arange(3)]).max() if len(self._particle_dofs) else 0.0
        return float(max(particles, 0.9 * np.abs(qvel[self._arm_dofs]).max()))

    def settle(self, min_s: float = 0.5) -> tuple[float, bool]:
        """Step until at rest (or :data:`MAX_SETTLE_S`); return the time taken and whether it came to rest."""
        m, d = self.sim.model, self.sim.data
        chunk = max(1, int(round(0.05 / m.opt.timestep)))
        mujoco.mj_step(m, d, nstep=int(round(min_s / m.opt.timestep)))
        waited = min_s
        while self.speed() > REST_SPEED_MPS and waited < MAX_SETTLE_S:
            mujoco.mj_step(m, d, nstep=chunk)
            waited += chunk * m.opt.timestep
        return waited, self.speed() <= REST_SPEED_MPS

    def drop(self, index: int, rng: np.random.Generator) -> None:
        """Teleport particle ``index`` above the middle of the bucket's mouth, at a random spot across."""
        sim = self.sim
        mouth = kinematics.BUCKET_INSIDE_POLYGON_M[1:3].mean(axis=0)
        above = sim.bucket_to_world(np.array([mouth[0], 0.0, mouth[1]]))
        y = rng.uniform(-0.8, 0.8) * kinematics.BUCKET_INNER_HALF_WIDTH_M
        sim.set_particle(index, above + np.array([rng.uniform(-0.02, 0.02), y, DROP_HEIGHT_M]))

    def measure(self, pose: int, settle_s: float, at_rest: bool) -> HoldSample:
        """Average the readings over :data:`AVERAGE_S` and count what the bucket carries."""
        sim = self.sim
        m, d = sim.model, sim.data
        n = max(1, int(round(AVERAGE_S / m.opt.timestep)))
        readings = np.zeros((n, 5))
        for k in range(n):
            mujoco.mj_step(m, d)
            readings[k] = instant_reading(sim).as_array()
        instantaneous = payload_mod.mass_eq8(*readings[:, :4].T, chassis_pitch_rad=readings[:, 4])
        mean = readings.mean(axis=0)
        inside, heaped = carried_particles(sim)
        masses = sim.particle_masses
        return HoldSample(pose=pose, particles_carried=int((inside | heaped).sum()),
                          particles_in_bucket=int(inside.sum()), mass_kg=float(masses[inside | heaped].sum()),
                          mass_in_bucket_kg=float(masses[inside].sum()), lift_rad=float(mean[0]),
                          tilt_rad=float(mean[1]), lift_torque_nm=float(mean[2]), tilt_torque_nm=float(mean[3]),
                          chassis_pitch_rad=float(mean[4]), settle_s=settle_s, at_rest=at_rest,
                          rattle_std_kg=float(np.std(instantaneous)))


def static_holds(config: ScoopConfig | None = None, poses: tuple[tuple[float, float], ...] = HOLD_POSES_RAD,
                 max_particles: int = MAX_PARTICLES, seed: int = 0) -> list[HoldSample]:
    """Fill the held bucket one particle at a time at each pose; one sample per new count 0 ... ``max_particles``.

    Args:
        config: scene configuration (particle size and mass, physics step); the pile layout is unused.
        poses: (lift, tilt) holds, rad.
        max_particles: the largest count (of carried particles) to measure.
        seed: seed of the drop positions.

    Returns:
        Samples in the order measured; a count is measured once per pose, the first time it is reached.
    """
    config = config or ScoopConfig()
    rng = np.random.default_rng(seed)
    samples: list[HoldSample] = []
    for pose_index, (lift, tilt) in enumerate(poses):
        hold = _Hold(config, lift, tilt, max_particles + SPARE_PARTICLES)
        waited, at_rest = hold.settle()
        seen: set[int] = set()
        dropped = 0
        while True:
            sample = hold.measure(pose_index, waited, at_rest)
            count = sample.particles_carried
            if count not in seen and count <= max_particles:
                seen.add(count)
                samples.append(sample)
            if count >= max_particles or dropped >= max_particles + SPARE_PARTICLES:
                break
            hold.drop(dropped, rng)
            dropped += 1
            waited, at_rest = hold.settle()
    return samples


def _errors(estimate: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    error = np.abs(np.asarray(estimate) - np.asarray(truth))
    if len(error) == 0:
        return {"mean_abs_error_kg": math.nan, "max_abs_error_kg": math.nan, "samples": 0}
    return {"mean_abs_error_kg": float(np.nanmean(error)), "max_abs_error_kg": float(np.nanmax(error)),
            "samples": int(len(error))}


def evaluate_holds(samples: list[HoldSample], calibration: payload_mod.PayloadCalibration | None = None,
                   noise_nm: float = 0.0, seed: int = 0) -> dict[str, Any]:
    """Both estimators against the true mass on static-hold samples.

    Args:
        samples: from :func:`static_holds`.
        calibration: the estimators' calibration (nominal by default).
        noise_nm: standard deviation of load-cell noise added to each (averaged) torque, N*m.
        seed: noise seed.

    Returns:
        Per estimator, the errors against the carried mass (``eq8``, ``eq4``) and against the mass
        inside the paper's quadrilateral (``*_vs_in_bucket``), and one row per sample.
    """
    calibration = calibration or payload_mod.PayloadCalibration()
    rng = np.random.default_rng(seed)
    a = {name: np.array([getattr(s, name) for s in samples], dtype=float)
         for name in ("lift_rad", "tilt_rad", "lift_torque_nm", "tilt_torque_nm", "chassis_pitch_rad", "mass_kg",
                      "mass_in_bucket_kg")}
    noise = rng.normal(0.0, noise_nm, (len(samples), 2)) if noise_nm > 0 else np.zeros((len(samples), 2))
    tau_l, tau_t = a["lift_torque_nm"] + noise[:, 0], a["tilt_torque_nm"] + noise[:, 1]
    eq8 = payload_mod.mass_eq8(a["lift_rad"], a["tilt_rad"], tau_l, tau_t, calibration, a["chassis_pitch_rad"])
    eq4 = payload_mod.mass_eq4(a["lift_rad"], a["tilt_rad"], tau_t, calibration, a["chassis_pitch_rad"])
    rows = [{"pose": s.pose, "carried": s.particles_carried, "in_bucket": s.particles_in_bucket,
             "true_kg": s.mass_kg, "eq8_kg": float(e8), "eq4_kg": float(e4), "lift_rad": s.lift_rad,
             "tilt_rad": s.tilt_rad, "chassis_pitch_rad": s.chassis_pitch_rad, "settle_s": s.settle_s,
             "at_rest": s.at_rest, "rattle_std_kg": s.rattle_std_kg}
            for s, e8, e4 in zip(samples, eq8, eq4)]
    return {
        "eq8": _errors(eq8, a["mass_kg"]),
        "eq4": _errors(eq4, a["mass_kg"]),
        "eq8_vs_in_bucket": _errors(eq8, a["mass_in_bucket_kg"]),
        "eq4_vs_in_bucket": _errors(eq4, a["mass_in_bucket_kg"]),
        "counts_covered": sorted({s.particles_carried for s in samples}),
        "samples_with_heaped_particles": int(sum(s.particles_carried != s.particles_in_bucket for s in samples)),
        "samples_not_at_rest": int(sum(not s.at_rest for s in samples)),
        "rattle_std_kg_max": float(max((s.rattle_std_kg for s in samples), default=math.nan)),
        "noise_nm": noise_nm,
        "rows": rows,
    }


def hold_records(samples: list[HoldSample], config: ScoopConfig) -> list[EpisodeRecord]:
    """The static holds as episode records (one per pose, one step per sample), for ``payload calibrate``.

    ``mass_in_bucket_kg`` holds the carried mass: what a scale would weigh when calibrating the robot.
    """
    records = []
    for pose in sorted({s.pose for s in samples}):
        record = EpisodeRecord(meta={"source": "autoscoop bench payload (static hold)", "pose": pose,
                                     "static": True, "autoscoop_version": __version__, "config": config.to_dict()})
        for i, s in enumerate(x for x in samples if x.pose == pose):
            record.append(time_s=float(i), state=np.zeros(STATE_SIZE).tolist(), action=[0.0, 0.0, 0.0], reward=0.0,
                          reward_progress=0.0, reward_mass=0.0, particles_in_bucket=s.particles_carried,
                          mass_in_bucket_kg=s.mass_kg, lift_rad=s.lift_rad, tilt_rad=s.tilt_rad,
                          lift_torque_nm=s.lift_torque_nm, tilt_torque_nm=s.tilt_torque_nm,
                          tip_world_m=[math.nan, math.nan, math.nan], penetrating=0.0)
        records.append(record)
    return records


def moving_scoops(config: ScoopConfig | None = None, episodes: int = 5, seed: int = 0,
                  calibration: payload_mod.PayloadCalibration | None = None) -> dict[str, Any]:
    """Both estimators, noise-free, at every control step of scripted scoops, against the true mass.

    Two readings per step: the instantaneous torques at the end of the step, and their mean over
    the step's physics steps (what the environment's load cell reports). Errors are reported over
    all steps, over the steps with the bucket clear of the pile (not penetrating and the tip more
    than a particle radius from it), and at the episodes' last steps (raised at the terminal point,
    or at the time limit). The true mass is the particles inside the bucket (docs/definitions.md); at the last
    step the error against every particle the bucket carries (inside or heaped) is given too.
    """
    from autoscoop.agents.loading import heuristic_for  # noqa: PLC0415 - the env is only needed here
    from autoscoop.envs.rollout import rollout  # noqa: PLC0415
    from autoscoop.envs.scoop import make_scoop_env  # noqa: PLC0415

    config = config or ScoopConfig()
    calibration = calibration or payload_mod.PayloadCalibration()
    env = make_scoop_env(config)
    sim = env.unwrapped.sim
    policy = heuristic_for(config)
    rows: dict[str, list] = {k: [] for k in ("truth", "carried", "eq8_instant", "eq4_instant", "eq8_mean",
                                             "eq4_mean", "clear", "last")}
    window = ReadingWindow(sim)

    def read(step: int, obs: np.ndarray, action: np.ndarray, reward: float, next_obs: np.ndarray,
             terminated: bool, truncated: bool, info: dict[str, Any]) -> None:
        if info["physics_error"]:
            window.take()  # the failed step's readings are not the next episode's
            return
        rows["truth"].append(info["mass_in_bucket_kg"])
        inside, heaped = carried_particles(sim)
        rows["carried"].append(float(sim.particle_masses[inside | heaped].sum()))
        for kind, r in (("instant", instant_reading(sim)), ("mean", window.take())):
            rows[f"eq8_{kind}"].append(float(payload_mod.mass_eq8(
                r.lift_rad, r.tilt_rad, r.lift_torque_nm, r.tilt_torque_nm, calibration, r.chassis_pitch_rad)))
            rows[f"eq4_{kind}"].append(float(payload_mod.mass_eq4(
                r.lift_rad, r.tilt_rad, r.tilt_torque_nm, calibration, r.chassis_pitch_rad)))
        rows["clear"].append(not info["penetrating"] and info["tip_to_pile_m"] > config.pile.radius_m)
        rows["last"].append(terminated or truncated)

    try:
        for episode in range(episodes):
            rollout(policy, env, seed + episode, transition_observers=(read,))
    finally:
        window.detach()
        env.close()
    a = {k: np.asarray(v, dtype=float) for k, v in rows.items()}
    clear, last, truth = a["clear"] > 0, a["last"] > 0, a["truth"]
    out: dict[str, Any] = {"episodes": episodes, "steps": int(len(truth)), "steps_clear_of_pile": int(clear.sum())}
    for name in ("eq8", "eq4"):
        for kind in ("mean", "instant"):
            estimate = a[f"{name}_{kind}"]
            out[f"{name}_{kind}"] = {"all_steps": _errors(estimate, truth),
                                     "bucket_clear_of_pile": _errors(estimate[clear], truth[clear]),
                                     "last_step": _errors(estimate[last], truth[last]),
                                     "last_step_vs_carried": _errors(estimate[last], a["carried"][last])}
    out["true_mass_last_step_kg"] = [float(v) for v in truth[last]]
    return out


def run_payload_bench(config: ScoopConfig | None = None, episodes: int = 5, seed: int = 0,
                      calibration: payload_mod.PayloadCalibration | None = None,
                      records_dir: Path | None = None, progress: bool = True,
                      poses: tuple[tuple[float, float], ...] = HOLD_POSES_RAD,
                      max_particles: int = MAX_PARTICLES) -> dict[str, Any]:
    """Static holds (noise-free and with ``env.load_cell_noise_nm``) and moving scoops; optionally write records.

    Args:
        config: scene configuration.
        episodes: scripted moving scoops (0: none).
        seed: seed of the drops, the noise and the first scoop.
        calibration: the estimators' calibration (nominal by default).
        records_dir: write the static holds there as episode records (for ``autoscoop payload calibrate``).
        progress: print what it is doing.
        poses: (lift, tilt) of the static holds, rad.
        max_particles: the largest particle count of the holds.

    Returns:
        ``static`` and ``static_with_noise`` (see :func:`evaluate_holds`), ``moving`` (see
        :func:`moving_scoops`), the calibration and the config.
    """
    config = config or ScoopConfig()
    calibration = calibration or payload_mod.PayloadCalibration()
    if progress:
        print(f"static holds at {len(poses)} poses, 0..{max_particles} particles ...", flush=True)
    samples = static_holds(config, poses=poses, max_particles=max_particles, seed=seed)
    clean = evaluate_holds(samples, calibration)
    noisy = evaluate_holds(samples, calibration, noise_nm=config.env.load_cell_noise_nm, seed=seed)
    noisy.pop("rows")
    if records_dir is not None:
        for i, record in enumerate(hold_records(samples, config)):
            record.save(Path(records_dir) / f"static_hold_pose{i}.npz")
    if progress:
        print(f"moving scoops: {episodes} scripted episodes ...", flush=True)
    moving = moving_scoops(config, episodes=episodes, seed=seed, calibration=calibration) if episodes > 0 else None
    return {
        "static": clean,
        "static_with_noise": noisy,
        "moving": moving,
        "hold_poses_rad": [list(p) for p in poses],
        "acceptance_eq8_max_abs_error_kg": 0.35,
        "calibration": {"lift_offset_nm": calibration.lift_offset_nm, "tilt_offset_nm": calibration.tilt_offset_nm,
                        "payload_com_in_bucket_m": list(calibration.payload_com_in_bucket_m)},
        "autoscoop_version": __version__,
        "config": config.to_dict(),
    }
