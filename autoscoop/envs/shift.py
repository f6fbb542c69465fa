"""The world of a loader's shift: the scooping environment on a pile that carries over from scoop to scoop, with
a hopper beside the loader's path (:class:`autoscoop.sim.shift_sim.ShiftSim`).

Each scoop is an ordinary episode of :class:`~autoscoop.envs.scoop.ScoopEnv` (same state, reward, time limit and
outcome); only its start differs: the pile and the loader are as the last cycle left them. The scripted carry,
dump and return between scoops step the unwrapped environment (:mod:`autoscoop.evaluation.shift`).
"""

from __future__ import annotations

import gymnasium as gym
from gymnasium.wrappers import TimeLimit

from autoscoop.core.config import RandomizeConfig, ScoopConfig
from autoscoop.core.shift_checks import check_shift_config
from autoscoop.envs.scoop import EndedEpisodeGuard, ScoopEnv
from autoscoop.sim.shift_sim import ShiftSim


class ShiftScoopEnv(ScoopEnv):
    """:class:`ScoopEnv` in a shift's scene: the pile carries over, a hopper stands by (see the module docstring).

    Args:
        config: the shift's config (:func:`shift_world_config`).
    """

    sim_type = ShiftSim


SCOOPS_PER_TRAINING_PILE = 15
"""Scoops :class:`RepeatedPileEnv` takes from one pile before it starts on a fresh one (a shift's 15 cycles)."""


class RepeatedPileEnv(ShiftScoopEnv):
    """A shift's pile scooped again and again without the carry, for training on the faces scoops leave.

    Each episode is an ordinary scoop (same state, reward, time limit and outcome as :class:`ScoopEnv`). Its
    pile is the one the last episode left, after :meth:`autoscoop.sim.shift_sim.ShiftSim.clear_for_next_scoop`
    (the load taken away, the pile settled, the loader set at its start pose before the new toe), for up to
    :data:`SCOOPS_PER_TRAINING_PILE` scoops; then, or when no pile is left on the path or the simulation
    diverged, a freshly settled pile. It always runs in its config's one world: a training curriculum's
    :meth:`set_randomize` leaves it as it is.

    Args:
        config: a config whose ``shift.*`` keys give the pile (:func:`shift_world_config` is applied to it with
            the ``randomize`` section emptied).
    """

    def __init__(self, config: ScoopConfig | None = None, render_mode: str | None = None) -> None:
        config = config or ScoopConfig()
        super().__init__(config=shift_world_config(config.replace(randomize=RandomizeConfig())),
                         render_mode=render_mode)
        self.scoops_on_pile = 0
        """scoops begun on the present pile, this one included."""

    def _start_world(self) -> None:
        sim = self.sim
        if sim.continuing and self.scoops_on_pile < SCOOPS_PER_TRAINING_PILE and sim.is_finite() \
                and sim.clear_for_next_scoop(self.np_random):
            self.scoops_on_pile += 1
            return
        sim.start_shift()
        sim.reset(self.np_random)
        self.scoops_on_pile = 1

    def set_randomize(self, randomize: RandomizeConfig) -> None:
        """Kept in its one world: a curriculum's randomised world does not reach the repeated pile."""


def make_repeated_pile_env(config: ScoopConfig | None = None) -> gym.Env:
    """:class:`RepeatedPileEnv` in a ``TimeLimit`` of ``env.max_episode_s``, inside an :class:`EndedEpisodeGuard`."""
    env = RepeatedPileEnv(config=config)
    return EndedEpisodeGuard(TimeLimit(env, max_episode_steps=env.config.max_episode_steps))


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
