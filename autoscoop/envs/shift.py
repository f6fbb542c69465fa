"""The world of a loader's shift: the scooping environment on a pile that carries over from scoop to scoop, with
a hopper beside the loader's path (:class:`autoscoop.sim.shift_sim.ShiftSim`).

Each scoop is an ordinary episode of :class:`~autoscoop.envs.scoop.ScoopEnv` (same state, reward, time limit and
outcome); only its start differs: the pile and the loader are as the last cycle left them. The scripted carry,
dump and return between scoops step the unwrapped environment (:mod:`autoscoop.evaluation.shift`).
"""

from __future__ import annotations

import gymnasium as gym
from gymnasium.wrappers import TimeLimit

from autoscoop.core.config import ScoopConfig
from autoscoop.core.shift_checks import check_shift_config
from autoscoop.envs.scoop import EndedEpisodeGuard, ScoopEnv
from autoscoop.sim.shift_sim import ShiftSim


class ShiftScoopEnv(ScoopEnv):
    """:class:`ScoopEnv` in a shift's scene: the pile carries over, a hopper stands by (see the module docstring).

    Args:
        config: the shift's config (:func:`shift_world_config`).
    """

    sim_type = ShiftSim


def shift_world_config(config: ScoopConfig) -> ScoopConfig:
    """The config a shift runs in: ``config`` with the shift's pile (``shift.pile_particles`` in ``shift.pile_layers``
    layers of rows ``shift.pile_across`` wide) in ``pile.n_particles``, ``pile.max_layers`` and ``pile.across``.

    Raises:
        ValueError: the shift's settings cannot work (:func:`autoscoop.core.shift_checks.check_shift_config`), naming
            the key.
    """
    check_shift_config(config)
    shift = config.shift
    return config.replace(pile=config.pile.replace(n_particles=shift.pile_particles, max_layers=shift.pile_layers,
                                                   across=shift.pile_across))


def make_shift_env(config: ScoopConfig) -> gym.Env:
    """A shift's environment for the scoops (``config`` from :func:`shift_world_config`): :class:`ShiftScoopEnv` in a
    ``TimeLimit`` of ``env.max_episode_s``, inside an :class:`EndedEpisodeGuard`, as every scoop runs."""
    env = ShiftScoopEnv(config=config)
    return EndedEpisodeGuard(TimeLimit(env, max_episode_steps=config.max_episode_steps))
