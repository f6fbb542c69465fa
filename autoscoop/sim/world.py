"""A randomised world: one episode's draw from the ``randomize`` ranges, and the config it makes.

:func:`draw_world` draws every quantity the ranges name (``RandomizeConfig.ranges()``), in a fixed
order, from the episode's generator; :func:`world_config` turns the draw into the episode's
:class:`~autoscoop.core.config.ScoopConfig` (pile, robot, env and sensor sections), which the
environment builds (or takes from its bank) and runs. A quantity without a range keeps the base
config's value and consumes no random numbers. Every drawn value is in the returned mapping, which
goes into ``info["world"]`` and the episode's record, so a failed episode can be traced to its world.

Quantised draws (a bank of compiled scenes and settled piles stays small): the particle radius to
the millimetre, the particle count to whole rows of ``pile.across``, the pile angle to 0.5 deg, what an earlier scoop took
to whole particles.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from autoscoop.core.config import ScoopConfig

ANGLE_STEP_DEG = 0.5
RADIUS_STEP_M = 0.001


def draw_world(config: ScoopConfig, rng: np.random.Generator) -> dict[str, Any]:
    """One episode's world: a value for every range in force (``config.randomize.ranges()``).

    Returns:
        Drawn values by range name (floats; ``torque_source`` and ``prescooped`` as booleans,
        ``torque_offset_nm`` as [lift, tilt]); empty when nothing is randomised.
    """
    ranges = config.randomize.ranges()
    out: dict[str, Any] = {}

    def uniform(name: str) -> float | None:
        if name not in ranges:
            return None
        low, high = ranges[name]
        return float(low) if low == high else float(rng.uniform(low, high))

    for name in ("pile_angle_deg", "particle_mass_kg", "particle_friction", "particle_radius_m", "n_particles",
                 "start_gap_m", "ground_friction", "bucket_friction", "torque_limit_scale", "actuator_speed_scale",
                 "load_cell_noise_nm", "sensor_delay_s", "joint_noise_rad", "speed_noise_mps", "range_noise_m",
                 "torque_noise_nm", "prescoop_particles"):
        value = uniform(name)
        if value is not None:
            out[name] = value
    if "pile_angle_deg" in out:
        out["pile_angle_deg"] = round(out["pile_angle_deg"] / ANGLE_STEP_DEG) * ANGLE_STEP_DEG
    if "prescoop_particles" in out:
        out["prescoop_particles"] = int(round(out["prescoop_particles"]))
    if "particle_radius_m" in out:
        out["particle_radius_m"] = round(round(out["particle_radius_m"] / RADIUS_STEP_M) * RADIUS_STEP_M, 6)
    if "n_particles" in out:
        across = config.pile.across
        out["n_particles"] = max(across, int(round(out["n_particles"] / across)) * across)
    if "torque_offset_nm" in ranges:
        low, high = ranges["torque_offset_nm"]
        out["torque_offset_nm"] = [float(v) for v in rng.uniform(low, high, 2)] if low != high else [float(low)] * 2
    if "torque_source_probability" in ranges:
        out["torque_source"] = bool(rng.random() < ranges["torque_source_probability"][0])
    if "prescooped_probability" in ranges:
        out["prescooped"] = bool(rng.random() < ranges["prescooped_probability"][0])
        if not out["prescooped"]:
            out.pop("prescoop_particles", None)
    return out


def world_config(config: ScoopConfig, world: dict[str, Any]) -> ScoopConfig:
    """The episode's config: ``config`` with the drawn values of ``world`` in place (same config if empty)."""
    if not world:
        return config
    pile, robot, env, sensor = config.pile, config.robot, config.env, config.sensor
    pile_changes = {key: world[name] for name, key in (("pile_angle_deg", "angle_deg"),
                                                       ("particle_mass_kg", "particle_mass_kg"),
                                                       ("particle_friction", "friction"),
                                                       ("particle_radius_m", "radius_m"),
                                                       ("n_particles", "n_particles")) if name in world}
    if "pile_angle_deg" in world:
        pile_changes["angle_mix_deg"] = ()
    robot_changes: dict[str, Any] = {key: world[key] for key in ("start_gap_m", "ground_friction", "bucket_friction")
                                     if key in world}
    torque = world.get("torque_limit_scale", 1.0)
    speed = world.get("actuator_speed_scale", 1.0)
    if torque != 1.0:
        robot_changes.update(lift_torque_limit_nm=robot.lift_torque_limit_nm * torque,
                             tilt_torque_limit_nm=robot.tilt_torque_limit_nm * torque,
                             wheel_torque_limit_nm=robot.wheel_torque_limit_nm * torque)
    if speed != 1.0:
        robot_changes.update(lift_speed_radps=robot.lift_speed_radps * speed,
                             tilt_speed_radps=robot.tilt_speed_radps * speed)
    env_changes: dict[str, Any] = {}
    if "torque_source" in world:
        env_changes["mass_source"] = "torque" if world["torque_source"] else "truth"
    if "load_cell_noise_nm" in world:
        env_changes["load_cell_noise_nm"] = world["load_cell_noise_nm"]
    sensor_changes = {key: world[name] for name, key in (("sensor_delay_s", "delay_s"),
                                                         ("joint_noise_rad", "joint_noise_rad"),
                                                         ("speed_noise_mps", "speed_noise_mps"),
                                                         ("range_noise_m", "range_noise_m"),
                                                         ("torque_noise_nm", "torque_noise_nm")) if name in world}
    return config.replace(pile=pile.replace(**pile_changes), robot=robot.replace(**robot_changes),
                          env=env.replace(**env_changes), sensor=sensor.replace(**sensor_changes))


def scene_key(config: ScoopConfig) -> tuple:
    """What a compiled scene depends on beyond per-episode model parameters: particle radius and count,
    whether they roll, and the physics step (a bank of scenes is keyed by it)."""
    pile = config.pile
    return (round(pile.radius_m, 6), pile.n_particles, pile.rolling, config.env.timestep_s)

