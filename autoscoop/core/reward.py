"""The paper's shaped reward (eq. 5-7), with its terms named.

    penetrate  <=>  min_i |tip - particle_i| <= Delta                         (eq. 7)
    P_t = 1 - tanh^2(|d_end| / s)  if penetrating, else  1 - tanh^2(|d_t| / s)   (eq. 5)
    r_t = P_t + c_w * min(w_t, 1)  if |d_end| <= epsilon, else  P_t          (eq. 6; mass above the rated
                                                                            load earns no more)

d_t: tip to the pile (m); d_end: tip to the terminal point (m); w_t: mass in bucket / rated load;
s: ``reward.distance_scale_m``, 1 m in the paper (our addition: over a workspace of half a metre,
s = 1 m leaves P_t between 0.8 and 1, a weak signal; a smaller s sharpens it).

Two additions for a world whose material varies (both off by default, the paper's reward):
``reward.fill_measure = scoop`` pays c_w * min(max(w_t, v_t), 1), v_t the volumetric fill, the
measure of a scoop's success (light earth fills the bucket by volume before it reaches the rated
mass); ``reward.c_overload`` > 0 takes c_overload * (w_t - w_o) off the bonus for mass above
w_o = ``reward.overload_from`` (1 by default: the rated load; below 1 the bonus peaks short of the
rated load, so that a scoop of heavy earth aims under it with room for the scatter of a scoop).
``reward.c_pitch`` > 0 costs c_pitch per degree of nose-down chassis pitch beyond
``reward.pitch_from_deg`` at every step (the term ``reward_pitch``): a heavy load carried far forward
tips the loader onto its front wheels, and a loader on its nose neither drives nor lifts well.
``reward.c_action_change`` > 0 costs c_action_change * u_t at every step (the term
``reward_action_change``), u_t = mean_i ((a_t,i - a_t-1,i) / 2)^2 in [0, 1] over the three normalised
actions, a_-1 = 0 (the loader starts still): a controller that flips its commands from one control
period to the next (bang-bang, a limit cycle short of the terminal point) pays for it, and a robot's
actuators are spared the jerk.
``reward.c_approach_height`` > 0 costs c_approach_height * (h_t - h_o) at every step for tip height h_t
above h_o = ``reward.approach_height_from_m`` until the tip first reaches the pile (the term
``reward_approach_height``): a bucket raised in front of the pile and dropped again before it cuts
costs a second of the cycle and the energy of the lift.
``reward.c_overload_step`` > 0 costs c_overload_step * (w_t - w_v) at every step for mass above
w_v = ``scoop.overload_fill`` in the bucket, what evaluation counts as an overload (the term
``reward_overload_step``): an overload is cheapest to shed at the pile, right after the cut, not short of
the terminal point.
``reward.c_energy`` > 0 costs c_energy * E_t at every step, E_t the actuators' positive mechanical work over the
control period, J (force times velocity at the wheel motors and the lift and tilt servos, braking counted zero;
the term ``reward_energy``): a scoop that winds up, or flips its servos, spends energy a shift pays for per tonne.
``reward.c_success`` > 0 pays c_success once, on reaching the terminal point loaded as a success is defined
(max(w_t, v_t) >= ``scoop.min_fill``; the term ``reward_success``): the bonus c_w * w_t pays a scoop just short
of a success almost as much as one just past it, so a controller whose scoops scatter about that line has no
reason to move them past it.
``reward.c_time`` > 0 costs c_time at every step (the term ``reward_time``): P_t pays up to 1 a step, so
with the time limit bootstrapped, lingering short of the terminal point (shaking particles out, say) and
reaching it later pays about as much as reaching it now; with c_time = 1 no step pays, and the mass
bonus is worth most when it comes soonest.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from autoscoop.core.config import RewardConfig


def is_penetrating(nearest_particle_m: float, config: RewardConfig) -> bool:
    """Eq. 7: the tip is within Delta of some particle's centre."""
    return nearest_particle_m <= config.delta_m


def is_success(reached: bool, w: float, volumetric_fill: float, min_fill: float) -> bool:
    """A scoop's success: the terminal point reached with the fill by mass (w) or by volume, whichever is higher,
    at least ``scoop.min_fill``."""
    return bool(reached and max(w, volumetric_fill) >= min_fill)


def action_change(previous: Sequence[float], action: Sequence[float]) -> float:
    """u_t: the mean over the action's components of ((a_t - a_t-1) / 2)^2, each clipped to [-1, 1]; 0 to 1."""
    if len(previous) != len(action):
        raise ValueError(f"action_change: {len(previous)} previous components against {len(action)}")
    changes = [(max(-1.0, min(1.0, float(a))) - max(-1.0, min(1.0, float(p)))) / 2.0
               for p, a in zip(previous, action, strict=True)]
    return sum(c * c for c in changes) / len(changes) if changes else 0.0


def scoop_reward(tip_to_pile_m: float, tip_to_terminal_m: float, penetrating: bool, w: float,
                 config: RewardConfig, volumetric_fill: float = 0.0,
                 chassis_pitch_rad: float = 0.0, command_change: float = 0.0,
                 approach_height_m: float | None = None,
                 overload_fill: float | None = None, actuator_work_j: float = 0.0,
                 min_fill: float | None = None) -> tuple[float, dict[str, float]]:
    """Reward of one step and its terms.

    Args:
        tip_to_pile_m: d_t, metres.
        tip_to_terminal_m: d_end, metres.
        penetrating: eq. 7.
        w: normalised mass in the bucket (paid up to 1: the rated load).
        config: c_w, epsilon, distance scale, fill measure, overload cost.
        volumetric_fill: v_t, the particles' volume over the bucket's capacity (``fill_measure = scoop``).
        chassis_pitch_rad: the chassis pitch, rad, positive nose down (``c_pitch`` > 0).
        command_change: u_t of :func:`action_change`, 0 to 1 (``c_action_change`` > 0).
        approach_height_m: the tip's height above the ground, m, while it has not yet reached the pile;
            ``None`` once it has (``c_approach_height`` > 0).
        overload_fill: ``scoop.overload_fill``, the fill factor above which a load is an overload
            (``c_overload_step`` > 0).
        actuator_work_j: the actuators' positive mechanical work over this control period, J (``c_energy`` > 0).
        min_fill: ``scoop.min_fill``, the fill (by mass or by volume, whichever is higher) of a success
            (``c_success`` > 0).

    Returns:
        (reward, {"reward_progress": P_t, "reward_mass": c_w * w_t or 0}, with "reward_pitch" where
        ``c_pitch`` > 0, "reward_action_change" where ``c_action_change`` > 0, "reward_approach_height"
        where ``c_approach_height`` > 0, "reward_overload_step" where ``c_overload_step`` > 0, "reward_energy" where
        ``c_energy`` > 0, "reward_success" where ``c_success`` > 0 and "reward_time" where ``c_time`` > 0); the terms
        sum to the reward.
    """
    distance = tip_to_terminal_m if penetrating else tip_to_pile_m
    progress = 1.0 - math.tanh(distance / config.distance_scale_m) ** 2
    mass = 0.0
    if tip_to_terminal_m <= config.epsilon_m:
        fill = max(w, volumetric_fill) if config.fill_measure == "scoop" else w
        mass = config.c_w * min(fill, 1.0)  # no more for an overload
        if config.c_overload and w > config.overload_from:
            mass -= config.c_overload * (w - config.overload_from)
    terms = {"reward_progress": progress, "reward_mass": mass}
    if config.c_pitch:
        excess_deg = max(math.degrees(chassis_pitch_rad) - config.pitch_from_deg, 0.0)
        terms["reward_pitch"] = -config.c_pitch * excess_deg
    if config.c_action_change:
        terms["reward_action_change"] = -config.c_action_change * command_change
    if config.c_approach_height:
        excess_m = 0.0 if approach_height_m is None else max(approach_height_m - config.approach_height_from_m, 0.0)
        terms["reward_approach_height"] = -config.c_approach_height * excess_m
    if config.c_overload_step:
        if overload_fill is None:
            raise ValueError("reward.c_overload_step needs the overload threshold (scoop.overload_fill)")
        terms["reward_overload_step"] = -config.c_overload_step * max(w - overload_fill, 0.0)
    if config.c_energy:
        if not math.isfinite(actuator_work_j) or actuator_work_j < 0.0:
            raise ValueError(f"actuator_work_j must be a finite, non-negative number of joules, got {actuator_work_j}")
        terms["reward_energy"] = -config.c_energy * actuator_work_j
    if config.c_success:
        if min_fill is None:
            raise ValueError("reward.c_success needs the fill of a success (scoop.min_fill)")
        reached = tip_to_terminal_m <= config.epsilon_m
        terms["reward_success"] = config.c_success if is_success(reached, w, volumetric_fill, min_fill) else 0.0
    if config.c_time:
        terms["reward_time"] = -config.c_time
    return float(sum(terms.values())), terms
