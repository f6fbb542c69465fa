"""A loader's shift: scoop after scoop from one pile into a hopper, and what it delivers per hour and per unit of energy.

Each cycle alternates the scoop policy (any :class:`~autoscoop.core.policy.Policy`, through the one
:func:`~autoscoop.envs.rollout.rollout`) and the scripted carry, dump and return
(:class:`~autoscoop.core.shift_script.CarryDumpScript`), on the world of :mod:`autoscoop.envs.shift`. After every
cycle it counts where each particle is (:mod:`autoscoop.core.shift_accounting`).

Units: masses kg, times s, energy kJ, distances m; x in the shift's first frame (from the pile's toe at the start
of the shift), so the pile's profiles show the face retreating.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from tqdm import tqdm

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig
from autoscoop.core.policy import Policy, config_for_policy
from autoscoop.core.shift_accounting import pile_profile
from autoscoop.core.shift_checks import HOPPER_WALL_M
from autoscoop.core.shift_script import HOPPER_PHASES, CarryDumpScript, Ranges, ScriptParams
from autoscoop.core.state import CommandLimits
from autoscoop.core.version import __version__, dependency_versions
from autoscoop.envs.rollout import rollout
from autoscoop.envs.shift import make_shift_env, shift_world_config
from autoscoop.evaluation.shift_film import ShiftFilm
from autoscoop.evaluation.workers import worker_pool
from autoscoop.sim.work_meter import WorkMeter

PROFILE_BIN_M = 0.02
"""Spacing of the points of the pile's profile, m."""
PHYSICS_ERROR = "physics_error"
"""Ends the list of timed-out phases when the simulation diverged during the script."""
EPISODE_SEEDS_PER_SHIFT = 1000
"""Cycle k of shift seed s scoops with episode seed ``s * 1000 + k``."""


def script_params(config: ScoopConfig) -> ScriptParams:
    """The scripted phases' settings for a shift's config (its hopper, start pose, limits and phase time limit)."""
    return ScriptParams(hopper_half_length_m=config.shift.hopper_length_m / 2, start_gap_m=config.robot.start_gap_m,
                        start_lift_rad=config.robot.start_lift_rad, start_tilt_rad=config.robot.start_tilt_rad,
                        phase_limit_s=config.shift.phase_limit_s, control_period_s=config.env.control_period_s,
                        limits=CommandLimits.for_robot(config.robot), hopper_wall_m=HOPPER_WALL_M)


def run_shift(policy: Policy, config: ScoopConfig, cycles: int, seed: int = 0, progress: bool = True,
              label: str | None = None, after_cycle: Callable[[dict[str, Any]], None] | None = None,
              film: ShiftFilm | None = None) -> dict[str, Any]:
    """Run one shift of ``cycles`` loading cycles with ``policy`` scooping.

    Args:
        policy: the scoop controller.
        config: the config (``shift.*`` for the pile and the hopper); the policy's state frame is laid over it.
        cycles: loading cycles to run; fewer when no pile is left on the loader's path (the last row's
            ``pile_exhausted``) or the simulation diverged.
        seed: the shift's seed: the pile's variant and each scoop's episode seed.
        progress: show a progress bar.
        label: the progress bar's name (default ``shift POLICY``).
        after_cycle: called with each cycle's row as it ends.
        film: films the shift (its frames stay in it).

    Returns:
        ``policy``, ``seed``, ``cycles`` (one row per cycle, :func:`_cycle_row`), ``totals``
        (:func:`shift_totals`), ``conditions`` (:func:`shift_conditions`), ``autoscoop_version``.

    Raises:
        ValueError: the shift's settings cannot work (naming the key), before any simulation.
    """
    world = shift_world_config(config_for_policy(policy, config))
    env = make_shift_env(world)
    scoop_env = env.unwrapped
    sim = scoop_env.sim
    meter = WorkMeter(sim.model, sim.data)
    sim.add_substep_observer(meter)
    if film is not None:
        film.attach(sim)
    script = CarryDumpScript(script_params(world))
    last_obs: list[np.ndarray] = []
    rows: list[dict[str, Any]] = []
    clock_s = 0.0
    bar = tqdm(range(cycles), desc=label or f"shift {policy.name}", unit="cycle", disable=not progress)
    try:
        for k in bar:
            meter.reset()
            outcome = rollout(policy, env, seed * EPISODE_SEEDS_PER_SHIFT + k,
                              transition_observers=[lambda *t: last_obs.append(t[4])])
            start_s = float(sim.data.time) - sim.elapsed_s
            scoop_work_j = meter.positive_work_j
            scooped = sim.particles_in_bucket()
            delivered_before = int(sim.delivered.sum())
            timed_out: list[str] = []
            steered = (0.0, 0.0)
            if not outcome.physics_error:
                timed_out = _carry_dump_return(scoop_env, script, last_obs[-1], world)
                if not timed_out or timed_out[-1] != PHYSICS_ERROR:
                    steered = sim.align_with_pile()
            account = sim.account()
            toe_x = sim.toe_x_m()
            cycle_s = float(sim.data.time) - start_s
            clock_s += cycle_s
            delivered = int(sim.delivered.sum()) - delivered_before
            mass = float(world.pile.particle_mass_kg)
            xs, heights = pile_profile(sim.particle_positions, world.pile.radius_m, account.pile, PROFILE_BIN_M)
            row = {
                "cycle": k + 1,
                "episode_seed": seed * EPISODE_SEEDS_PER_SHIFT + k,
                "scoop_success": outcome.success,
                "scoop_reached": outcome.reached,
                "physics_error": outcome.physics_error or PHYSICS_ERROR in timed_out or not sim.is_finite(),
                "mass_scooped_kg": outcome.mass_kg,
                "mass_delivered_kg": delivered * mass,
                "spilled_on_way_kg": float((scooped & ~sim.delivered & ~account.bucket).sum()) * mass,
                "fill_factor": outcome.fill_factor,
                "volumetric_fill": outcome.volumetric_fill,
                "scoop_time_s": outcome.steps * world.env.control_period_s,
                "cycle_time_s": cycle_s,
                "energy_kj": meter.positive_work_j / 1000.0,
                "energy_scoop_kj": scoop_work_j / 1000.0,
                "wheel_travel_m": meter.wheel_travel_m,
                "chassis_travel_m": meter.chassis_travel_m,
                "wheel_slip": meter.slip,
                "timed_out_phases": timed_out,
                "phase_times_s": dict(script.phase_times_s) if not outcome.physics_error else {},
                "steered_offset_m": steered[0],
                "steered_heading_deg": steered[1],
                "shift_time_s": clock_s,
                "particles": account.counts(),
                "conserved": account.balanced(),
                "toe_retreat_m": sim.toe_shift_m + toe_x,
                "pile_exhausted": not math.isfinite(toe_x),
                "profile_x_m": [float(x) + sim.toe_shift_m for x in xs],
                "profile_height_m": [float(h) for h in heights],
            }
            rows.append(row)
            if after_cycle is not None:
                after_cycle(row)
            bar.set_postfix(fill=f"{outcome.fill_factor:.2f}", delivered=f"{sum(r['mass_delivered_kg'] for r in rows):.1f}kg")
            if row["physics_error"] or row["pile_exhausted"]:
                break
    finally:
        sim.remove_substep_observer(meter)
        if film is not None:
            film.detach()
        env.close()
    return {"policy": policy.name, "seed": seed, "cycles": rows, "totals": shift_totals(rows),
            "conditions": shift_conditions(world), "autoscoop_version": __version__,
            "dependencies": dependency_versions()}


def _carry_dump_return(env: Any, script: CarryDumpScript, state: np.ndarray, config: ScoopConfig) -> list[str]:
    """Step ``env`` (the unwrapped scoop environment) with the script from the scoop's end to the next scoop's start:
    the hopper is spotted as the script drives to it and leaves, with what it received, after the back-off.

    Returns:
        The phases that ended on their time limit (then :data:`PHYSICS_ERROR` if the simulation diverged); the time
        of each phase is in ``script.phase_times_s``.
    """
    sim = env.sim
    hopper_x = -config.shift.haul_distance_m  # the toe was at x = 0 when the scoop began
    toe_x = sim.toe_x_m()
    script.start(env.commanded_targets)
    spotted = False
    while True:
        tip_x = float(sim.tip_world[0])
        action = script.act(state, Ranges(to_hopper_m=hopper_x - tip_x, to_pile_m=toe_x - tip_x))
        if script.phase in HOPPER_PHASES and not spotted:
            sim.spot_hopper(hopper_x)
            spotted = True
        elif script.phase not in HOPPER_PHASES and spotted:
            sim.deliver()
            toe_x = sim.toe_x_m()
            spotted = False
        if script.done:
            return script.timed_out
        state, _, _, _, info = env.step(action)
        if info["physics_error"]:
            return [*script.timed_out, PHYSICS_ERROR]


def shift_totals(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """A shift's totals from its cycle rows.

    Returns:
        ``cycles``; ``delivered_kg``; ``shift_time_s``; ``delivered_t_per_h`` (delivered tonnes per hour of
        shift time); ``energy_kj`` and ``energy_kj_per_t`` (positive actuator work per delivered tonne);
        ``spilled_kg`` (off the pile, bucket and hopper at the end) and ``spillage_share`` (of the mass
        scooped); ``failed_scoop_share`` (scoops that did not succeed); ``wheel_slip`` (over the whole
        shift); ``fill_first5``, ``fill_last5`` and ``fill_last5_over_first5``; ``conserved`` (every cycle
        accounted for every particle); ``pile_exhausted`` (the shift ended early: no pile left on the path).
    """
    if not rows:
        return {"cycles": 0}
    delivered = sum(r["mass_delivered_kg"] for r in rows)
    scooped = sum(r["mass_scooped_kg"] for r in rows)
    time_s = rows[-1]["shift_time_s"]
    energy = sum(r["energy_kj"] for r in rows)
    energy_scoop = sum(r["energy_scoop_kj"] for r in rows)
    wheel = sum(r["wheel_travel_m"] for r in rows)
    chassis = sum(r["chassis_travel_m"] for r in rows)
    fills = [r["fill_factor"] for r in rows]
    first, last = float(np.mean(fills[:5])), float(np.mean(fills[-5:]))
    return {
        "cycles": len(rows),
        "delivered_kg": delivered,
        "scooped_kg": scooped,
        "shift_time_s": time_s,
        "delivered_t_per_h": (delivered / 1000.0) / (time_s / 3600.0) if time_s > 0 else math.nan,
        "energy_kj": energy,
        "energy_kj_per_t": energy / (delivered / 1000.0) if delivered > 0 else math.nan,
        "energy_scoop_kj": energy_scoop,
        "energy_scoop_share": energy_scoop / energy if energy > 0 else math.nan,
        "spilled_on_way_kg": sum(r["spilled_on_way_kg"] for r in rows),
        "spillage_share": sum(r["spilled_on_way_kg"] for r in rows) / scooped if scooped > 0 else math.nan,
        "failed_scoop_share": float(np.mean([not r["scoop_success"] for r in rows])),
        "wheel_slip": 1.0 - chassis / wheel if wheel > 0 else math.nan,
        "fill_first5": first,
        "fill_last5": last,
        "fill_last5_over_first5": last / first if first > 0 else math.nan,
        "conserved": all(r["conserved"] for r in rows),
        "pile_exhausted": bool(rows[-1]["pile_exhausted"]),
        "physics_errors": sum(bool(r["physics_error"]) for r in rows),
    }


def shift_conditions(config: ScoopConfig) -> dict[str, Any]:
    """The conditions a productivity figure must state (after ISO 9245): material, density, state, operation, haul,
    and what receives the load; in the scale model's own units."""
    pile, shift = config.pile, config.shift
    volume_m3 = 4.0 / 3.0 * math.pi * pile.radius_m ** 3
    return {
        "material": f"spheres of radius {pile.radius_m:g} m, {pile.particle_mass_kg:g} kg each (a scale model of gravel)",
        "particle_mass_kg": pile.particle_mass_kg,
        "particle_radius_m": pile.radius_m,
        "particle_density_kg_m3": pile.particle_mass_kg / volume_m3,
        "pile_particles": pile.n_particles,
        "pile_mass_kg": pile.n_particles * pile.particle_mass_kg,
        "pile_angle_deg": pile.angle_deg,
        "pile_width_m": 2 * pile.radius_m * pile.across,
        "state": "loose (a pile of free particles)",
        "operation": "I-cycle loading: scoop, back out, drive to the hopper spotted between loader and pile, dump, "
                     "curl back while the hopper leaves, return",
        "haul_distance_m": shift.haul_distance_m,
        "receiver": f"hopper {shift.hopper_length_m:g} m x {shift.hopper_width_m:g} m, rim {shift.hopper_height_m:g} m high",
        "rated_load_kg": config.reward.rated_load_kg,
        "max_speed_mps": config.robot.max_speed_mps,
    }


def run_shifts(specs: list[str], config: ScoopConfig, cycles: int, seeds: list[int], workers: int = 1,
               trust: bool = False, progress: bool = True, film: ShiftFilm | None = None) -> list[dict[str, Any]]:
    """Run a shift for every policy and seed: the policies side by side on the same shifts.

    Args:
        specs: policies as :func:`autoscoop.agents.loading.load_policy` names them (``default``, ``heuristic``, a file).
        config: the config (``shift.*``).
        cycles: loading cycles per shift.
        seeds: the shifts' seeds, the same for every policy.
        workers: processes sharing the shifts (:func:`~autoscoop.evaluation.workers.worker_pool`; the results do not depend on it).
        trust: allow an SB3 .zip policy (loading one unpickles it).
        progress: show progress bars.
        film: films the first shift (the first policy's, on the first seed), run in this process.

    Returns:
        One :func:`run_shift` dict per (policy, seed), the policies in order, each over ``seeds``, with ``policy`` the
        spec as given.

    Raises:
        ValueError: the shift's settings cannot work, or a policy cannot be loaded, before any simulation.
    """
    shift_world_config(config)  # every settings error before the first shift
    for spec in specs:
        load_policy(spec, config, trust=trust)
    jobs = [(spec, seed) for spec in specs for seed in seeds]
    filmed = []
    if film is not None:  # rendering stays in this process
        filmed = [_shift_of_spec(*jobs[0], config.to_dict(), cycles, trust, progress, film)]
        jobs = jobs[1:]
    if workers == 1 or len(jobs) <= 1:
        return filmed + [_shift_of_spec(spec, seed, config.to_dict(), cycles, trust, progress) for spec, seed in jobs]
    with worker_pool(min(workers, len(jobs))) as pool:
        futures = [pool.submit(_shift_of_spec, spec, seed, config.to_dict(), cycles, trust, False) for spec, seed in jobs]
        bar = tqdm(futures, desc=f"shifts ({min(workers, len(jobs))} workers)", unit="shift", disable=not progress)
        return filmed + [future.result() for future in bar]


def _shift_of_spec(spec: str, seed: int, config: dict[str, Any], cycles: int, trust: bool, progress: bool,
                   film: ShiftFilm | None = None) -> dict[str, Any]:
    """One shift of the policy named ``spec`` (in a worker process, or here)."""
    built = ScoopConfig.from_dict(config)
    result = run_shift(load_policy(spec, built, trust=trust), built, cycles, seed=seed, progress=progress,
                       label=f"shift {spec} seed {seed}", film=film)
    return {**result, "policy": spec}
