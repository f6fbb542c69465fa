"""The scooping environment behind the ``autoscoop/`` Gymnasium ids: one continuous scoop of a particle pile by
a skid-steer loader."""

from __future__ import annotations

import copy
from collections import deque
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.wrappers import TimeLimit

from autoscoop.core import state as state_mod
from autoscoop.core.config import RandomizeConfig, ScoopConfig
from autoscoop.core.reward import action_change, is_penetrating, is_success, scoop_reward
from autoscoop.core.sensing import RawReadings, SensorNoise, add_noise, delay_steps
from autoscoop.core.state import CommandLimits, Measurements
from autoscoop.sim.capacity import volumetric_fill
from autoscoop.sim.load_cell import chassis_pitch_rad
from autoscoop.sim.scene import ScoopSim
from autoscoop.sim.work_meter import WorkMeter
from autoscoop.sim.world import draw_world, scene_key, world_config


class ScoopEnv(gym.Env):
    """A Komodo-style skid-steer loader scoops a pile of spherical particles (MuJoCo).

    The robot starts with its bucket low and level, ``robot.start_gap_m`` in front of the pile's toe.
    Within ``env.max_episode_s`` (8 s) it must drive in, fill the bucket, and lift it clear to the
    terminal point, which ends the episode with success (paper: Azulay and Shapiro, IEEE Access 2021).

    ## Action space
    ``Box(-1, 1, (3,), float32)``. Each action moves its commanded target by ``action * range``,
    clipped to the limits (the paper's code); the lift and tilt servos then move toward their
    targets at the linear actuators' bounded speed and force. NaN or inf raises ``ValueError``;
    values outside [-1, 1] are clipped.

    | index | name  | target moved                  | range of the target      | unit | actuator (XML)        |
    |-------|-------|-------------------------------|--------------------------|------|-----------------------|
    | 0     | drive | forward speed                 | [-0.1, 0.1]              | m/s  | wheel_fl/fr/rl/rr     |
    | 1     | lift  | lift angle (+ lowers the arm) | [-0.10, 0.32]            | rad  | lift (joint lift)     |
    | 2     | tilt  | tilt angle (+ tips edge down) | [-0.50, 0.90]            | rad  | tilt (joint tilt)     |

    ## Observation space
    ``Box(-inf, inf, (12,), float32)``: the paper's state, built by :func:`autoscoop.core.state.build_state`.
    Chassis frame: x forward from the chassis centre, z up from the ground.

    | index | name    | meaning                                  | unit | source (XML name)                 |
    |-------|---------|------------------------------------------|------|-----------------------------------|
    | 0     | w       | mass in bucket / rated load (7 kg)       | -    | particles inside the bucket       |
    | 1     | tip_x   | cutting edge x, chassis frame            | m    | kinematics of lift, tilt (site tip) |
    | 2     | tip_z   | cutting edge z, chassis frame            | m    | kinematics (site tip)             |
    | 3     | joint_x | tilt joint x, chassis frame              | m    | kinematics (site bucket_joint)    |
    | 4     | joint_z | tilt joint z, chassis frame              | m    | kinematics (site bucket_joint)    |
    | 5     | d_pile  | tip to the nearest particle surface outside the bucket | m | particle_* bodies   |
    | 6     | v       | forward speed, wheel odometry            | m/s  | sensors wheel_*_vel               |
    | 7     | lift    | lift angle                               | rad  | sensor lift_pos                   |
    | 8     | tilt    | tilt angle                               | rad  | sensor tilt_pos                   |
    | 9-11  | dv, dlift, dtilt | change since the previous step  | m/s, rad, rad |                          |

    With ``env.mass_source = torque``, w comes instead from the lift and tilt torques (sensors
    ``lift_torque``, ``tilt_torque``) averaged over the control period, plus ``env.load_cell_noise_nm``
    of noise, through paper eq. 8 (:mod:`autoscoop.core.payload`, :class:`autoscoop.sim.load_cell.TorqueMassSensor`).

    ## Reward (paper eq. 5-7)
    ``P_t = 1 - tanh^2(d_end)`` while penetrating (tip within ``reward.delta_m`` of a particle centre),
    else ``1 - tanh^2(d_t)``; plus ``reward.c_w * w_t`` on the step the tip comes within
    ``reward.epsilon_m`` of the terminal point (``reward.terminal_dx_m`` from the toe,
    ``reward.terminal_z_m`` high). ``info["reward_progress"] + info["reward_mass"] == reward``.
    The reward's ``w_t`` is always the counted mass (particles inside the bucket), whatever
    ``env.mass_source`` feeds the state: with the torque source the policy sees what the robot
    would, while the reward still pays for what the bucket really holds (paid for the estimate,
    a learner finds that quick, empty lifts read as load).
    ``d_end`` is measured in the arm's plane (world x and z): the terminal point marks a reach and a
    height over the pile across the bucket's width, as in the paper's planar problem. The state
    carries no lateral position, and a skid-steer pushed into a jittered pile yaws a few centimetres
    sideways, which the policy can neither see nor undo.

    ## Episode end
    Terminated on success or on a physics error (NaN state or a MuJoCo instability warning:
    ``info["physics_error"]``). Truncated by Gymnasium's ``TimeLimit`` after ``env.max_episode_s``.

    ## Info
    ``reward_progress``, ``reward_mass``, ``particles_in_bucket``, ``mass_in_bucket_kg``,
    ``fill_factor`` (mass / rated load), ``penetrating``, ``success``, ``cycle_time_s`` (on success),
    ``spilled`` (particles that were in the bucket and are not now), ``physics_error``,
    ``elapsed_s``, ``tip_to_pile_m``, ``tip_to_terminal_m``, ``lift_torque_nm``, ``tilt_torque_nm``.

    ## Version History
    Each id is this class with config keys of its own (``gym.spec(ID).kwargs``, :mod:`autoscoop.envs`).

    * ``autoscoop/ScoopRobot-v1``: the world the shipped ``default`` policy is trained in: the randomised
      ``robot`` world (``randomize.preset=robot``, docs/randomize.md), the state's tip and bucket joint in the
      level frame (``sensor.level_with_imu``), and the reward of the ``robot_smooth`` recipe with DDPG's
      ``reward.c_w`` (``fill_measure=scoop``, ``c_overload``, ``distance_scale_m``, ``c_action_change``).
    * ``autoscoop/Scoop-v1``: the paper's world as :class:`ScoopConfig` gives it. The speed reading is the
      wheels' mean speed over ``sensor.odometry_window_steps`` (2) physics steps, as an encoder counts it.
    * ``autoscoop/Scoop-v0``: the paper's world with the one-step odometry (``sensor.odometry_window_steps=1``):
      the instantaneous wheel speed, which rings at the physics step while the wheels push into the pile.
      Its observations are those of the first version, to the bit; success and the other metrics are
      counted as in v1.

    Args:
        config: the scene and task configuration; defaults to :class:`ScoopConfig`.
        render_mode: ``"rgb_array"`` or ``None``.
        overrides: dotted config keys, e.g. ``**{"pile.angle_deg": 25}``.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}
    sim_type: type[ScoopSim] = ScoopSim
    """the simulator the environment builds from its config (a shift's world adds a hopper to it)"""

    def __init__(self, config: ScoopConfig | None = None, render_mode: str | None = None,
                 **overrides: Any) -> None:
        config = config or ScoopConfig()
        if overrides:
            config = config.with_overrides(overrides)
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode {render_mode!r} is not supported; use one of {self.metadata['render_modes']}")
        self.config = config
        self.episode_config = config
        """this episode's config: ``config`` with a randomised world's draws in place (``info["world"]``)"""
        self.world: dict[str, Any] = {}
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": int(round(1.0 / config.env.control_period_s))}
        self.sim = self.sim_type(config)
        self._scenes = {scene_key(config): self.sim}
        self.limits = CommandLimits.for_robot(config.robot)
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(state_mod.ACTION_SIZE,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(state_mod.STATE_SIZE,), dtype=np.float32)
        self._terminal_xz = np.array([config.reward.terminal_dx_m, config.reward.terminal_z_m])
        self._mass_estimator = None
        self._renderer = None
        self._targets = np.zeros(3)
        self._previous: Measurements | None = None
        self._ever_inside = np.zeros(config.pile.n_particles, dtype=bool)
        self._last_obs = np.zeros(state_mod.STATE_SIZE, dtype=np.float32)
        self._instabilities = 0
        self._noise = SensorNoise()
        self._noise_rng: np.random.Generator | None = None
        self._delay_steps = 0
        self._sensed: deque[Measurements] = deque(maxlen=1)
        self._work_meters: dict[ScoopSim, WorkMeter] = {}  # per scene, attached where reward.c_energy > 0

    # ------------------------------------------------------------------ Gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """Start an episode on a (re)settled pile variant, the loader at its start pose.

        Args:
            seed: seeds the episode's randomness (Gymnasium's rule: only when given).
            options: no reset options are supported yet; ``None`` or ``{}``. Any key raises
                ``ValueError`` naming it, rather than being silently ignored.
        """
        if options:
            raise ValueError(f"ScoopEnv.reset: unknown option(s) {sorted(map(str, options))}; "
                             "no reset options are supported (pass options=None or {})")
        super().reset(seed=seed)
        if self._mass_estimator is not None:  # the last episode's load cell stops observing the sim
            self._mass_estimator.detach()
            self._mass_estimator = None
        self._start_world()
        cfg = self.episode_config
        self._targets = np.array([0.0, cfg.robot.start_lift_rad, cfg.robot.start_tilt_rad])
        self._ever_inside = np.zeros(cfg.pile.n_particles, dtype=bool)
        self._previous = None
        self._previous_action = np.zeros(state_mod.ACTION_SIZE)  # the loader starts still (reward.c_action_change)
        self._reached_pile = False  # the tip has touched the pile (reward.c_approach_height)
        self._instabilities = self.sim.instability_count()
        if cfg.env.mass_source == "torque":
            from autoscoop.sim.load_cell import TorqueMassSensor  # noqa: PLC0415 - optional until used
            offset = tuple(self.world.get("torque_offset_nm", (0.0, 0.0)))
            self._mass_estimator = TorqueMassSensor.for_env(cfg, self.np_random, offset_nm=offset)
        self._noise = SensorNoise.from_config(cfg.sensor)
        self._noise_rng = None if self._noise.silent else np.random.default_rng(int(self.np_random.integers(2**63)))
        self._delay_steps = delay_steps(cfg.sensor.delay_s, cfg.env.timestep_s)
        # the delay line: readings taken, the oldest first (the first is this instant's, the robot at rest)
        self._sensed = deque([self._sense()] if self._delay_steps else [], maxlen=self._delay_steps // cfg.substeps + 1)
        obs, info = self._observe()
        info["physics_error"] = not np.all(np.isfinite(obs))
        return obs, info

    def _start_world(self) -> None:
        """This episode's world: draw it (a ``randomize`` section in force), pick its scene, reset the sim."""
        base = self.config
        if not base.randomize.active:
            self.sim.reset(self.np_random)
            return
        self.world = draw_world(base, self.np_random)
        cfg = self.episode_config = world_config(base, self.world)
        key = scene_key(cfg)
        if key not in self._scenes:
            self._scenes[key] = ScoopSim(cfg)
        if self._scenes[key] is not self.sim:
            self.close()  # a renderer belongs to one model
        self.sim = self._scenes[key]
        self.sim.apply_parameters(cfg)
        self.sim.reset(self.np_random, pile=cfg.pile, start_gap_m=cfg.robot.start_gap_m,
                       prescoop_particles=self.world.get("prescoop_particles"))

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        self._targets = state_mod.advance_targets(self._targets, action, self.limits)
        cfg = self.episode_config
        change = action_change(self._previous_action, action) if cfg.reward.c_action_change else 0.0
        self._previous_action = np.array(action, dtype=float)
        period = cfg.env.control_period_s
        lift_rate, tilt_rate = state_mod.servo_rate(
            self._targets[1:], [self.sim.lift_setpoint_rad, self.sim.tilt_setpoint_rad], period,
            [cfg.robot.lift_speed_radps, cfg.robot.tilt_speed_radps])
        self.sim.command(self._targets[0], lift_rate, tilt_rate)
        meter = self._work_meter() if cfg.reward.c_energy else None
        if meter is not None:
            meter.reset()
        # the readings the policy gets are sensor.delay_s old: taken that many physics steps before
        # the end of a control period (this one, or one still in the delay line)
        late = self._delay_steps % cfg.substeps
        if late:
            self.sim.step(cfg.substeps - late)
            self._sensed.append(self._sense())
            self.sim.step(late)
        else:
            self.sim.step(cfg.substeps)
            if self._delay_steps:
                self._sensed.append(self._sense())

        if not self.sim.is_finite() or self.sim.instability_count() > self._instabilities:
            info = self._physics_error_info()
            return self._last_obs.copy(), 0.0, True, False, info

        obs, info = self._observe()
        # the reward's w is the counted fill factor, rounded as the state's w is (float32): with the
        # truth source the same number as obs[0]; with the torque source the true load, not the estimate
        pitch = chassis_pitch_rad(self.sim) if cfg.reward.c_pitch else 0.0
        self._reached_pile = self._reached_pile or info["penetrating"]
        approach_height = None if self._reached_pile else float(self.sim.tip_world[2])
        reward, terms = scoop_reward(info["tip_to_pile_m"], info["tip_to_terminal_m"], info["penetrating"],
                                     float(np.float32(info["fill_factor"])), cfg.reward, info["volumetric_fill"],
                                     chassis_pitch_rad=pitch, command_change=change,
                                     approach_height_m=approach_height, overload_fill=cfg.scoop.overload_fill,
                                     actuator_work_j=0.0 if meter is None else meter.positive_work_j,
                                     min_fill=cfg.scoop.min_fill)
        info.update(terms)
        terminated = info["reached"]  # the scoop ends at the terminal point, loaded or not
        return obs, float(reward), bool(terminated), False, info

    def _work_meter(self) -> WorkMeter:
        """The work meter of the scene in use (``reward.c_energy``), attached to it the first time it is asked for."""
        meter = self._work_meters.get(self.sim)
        if meter is None:
            meter = self._work_meters[self.sim] = WorkMeter(self.sim.model, self.sim.data)
            self.sim.add_substep_observer(meter)
        return meter

    @property
    def commanded_targets(self) -> np.ndarray:
        """The commanded targets now: forward speed m/s, lift rad, tilt rad (each action moves them)."""
        return self._targets.copy()

    @property
    def state_frame(self) -> str:
        """The frame of the state's tip and joint positions: ``level`` with ``sensor.level_with_imu``, else ``chassis``."""
        return "level" if self.config.sensor.level_with_imu else "chassis"

    def use_state_frame(self, frame: str) -> None:
        """Build the state in ``frame`` (``chassis`` or ``level``: ``sensor.level_with_imu``) from the next reset on;
        the rollout loop calls it with the frame a policy file declares."""
        if frame not in state_mod.STATE_FRAMES:
            raise ValueError(f"state frame {frame!r} is not one of {state_mod.STATE_FRAMES}")
        if frame == self.state_frame:
            return
        level = {"sensor.level_with_imu": frame == "level"}
        self.config = self.config.with_overrides(level)
        self.episode_config = self.episode_config.with_overrides(level)

    def set_randomize(self, randomize: RandomizeConfig) -> None:
        """Use another ``randomize`` section from the next reset on (a training curriculum widens the world)."""
        self.config = self.config.replace(randomize=randomize)

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        import mujoco  # noqa: PLC0415

        if self._renderer is None:
            self._renderer = mujoco.Renderer(self.sim.model, height=480, width=640)
        self._renderer.update_scene(self.sim.data, camera="side")
        return self._renderer.render()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ------------------------------------------------------------------ internals
    def _pile_geometry(self) -> tuple[np.ndarray, float, float]:
        """(particles inside the bucket, tip to the pile's surface m, tip to the nearest particle centre m), now."""
        sim = self.sim
        inside = sim.particles_in_bucket()
        offsets = sim.particle_positions - sim.tip_world
        distances = np.sqrt(np.einsum("ij,ij->i", offsets, offsets))
        outside = ~inside
        radius = self.episode_config.pile.radius_m
        tip_to_pile = float(max(distances[outside].min() - radius, 0.0)) if outside.any() else 0.0
        nearest = float(distances.min()) if len(distances) else np.inf
        return inside, tip_to_pile, nearest

    def _sense(self, geometry: tuple[np.ndarray, float, float] | None = None) -> Measurements:
        """What the robot's sensors read now, through the link's noise (``sensor.*``); the mass is the
        load cell's estimate (torque source) or the counted mass."""
        sim = self.sim
        inside, tip_to_pile, _ = geometry or self._pile_geometry()
        if self._mass_estimator is None:
            mass = float(sim.particle_masses[inside].sum())
        else:
            mass = self._mass_estimator.estimate(sim)
        lift, tilt, speed = sim.lift_rad, sim.tilt_rad, sim.odometry_speed_mps
        if self._noise_rng is not None:
            noisy = add_noise(RawReadings(lift_rad=lift, tilt_rad=tilt, speed_mps=speed, range_m=tip_to_pile,
                                             tilt_torque_nm=0.0, lift_torque_nm=0.0), self._noise, self._noise_rng)
            lift, tilt, speed, tip_to_pile = noisy.lift_rad, noisy.tilt_rad, noisy.speed_mps, noisy.range_m
        # the IMU's pitch levels the arm's points (sensor.level_with_imu); its noise is the joints' (an angle)
        pitch = 0.0
        if self.episode_config.sensor.level_with_imu:
            pitch = chassis_pitch_rad(sim)
            if self._noise_rng is not None and self._noise.joint_rad:
                pitch += float(self._noise_rng.normal(0.0, self._noise.joint_rad))
        return Measurements(mass_kg=mass, pile_distance_m=tip_to_pile, speed_mps=speed, lift_rad=lift, tilt_rad=tilt,
                            chassis_pitch_rad=pitch)

    def _observe(self) -> tuple[np.ndarray, dict[str, Any]]:
        sim, cfg = self.sim, self.episode_config
        geometry = self._pile_geometry()
        inside, tip_to_pile, nearest = geometry
        self._ever_inside |= inside
        true_mass = float(sim.particle_masses[inside].sum())
        tip = sim.tip_world
        tip_to_terminal = float(np.linalg.norm(tip[[0, 2]] - self._terminal_xz))  # in the arm's plane: see docstring
        # without a delay, the readings are this instant's; with one, the oldest in the delay line
        now = self._sense(geometry) if not self._delay_steps else self._sensed[0]
        obs = state_mod.build_state(now, self._previous, cfg.reward.rated_load_kg)
        self._previous = now
        self._last_obs = obs
        fill = true_mass / cfg.reward.rated_load_kg
        particles = int(inside.sum())
        volumetric = volumetric_fill(particles, cfg.pile.radius_m)
        reached = tip_to_terminal <= cfg.reward.epsilon_m
        info: dict[str, Any] = {
            "particles_in_bucket": particles,
            "mass_in_bucket_kg": true_mass,
            "fill_factor": fill,
            "volumetric_fill": volumetric,
            "penetrating": is_penetrating(nearest, cfg.reward),
            "reached": bool(reached),
            "success": is_success(reached, fill, volumetric, cfg.scoop.min_fill),
            "overloaded": bool(fill > cfg.scoop.overload_fill),
            "spilled": int((self._ever_inside & ~inside).sum()),
            "physics_error": False,
            "elapsed_s": sim.elapsed_s,
            "pile_angle_deg": sim.pile_angle_deg,
            "tip_to_pile_m": tip_to_pile,
            "tip_to_terminal_m": tip_to_terminal,
            "lift_torque_nm": sim.lift_torque_nm,
            "tilt_torque_nm": sim.tilt_torque_nm,
            "world": copy.deepcopy(self.world),
        }
        if reached:
            info["cycle_time_s"] = sim.elapsed_s
        return obs, info

    def _physics_error_info(self) -> dict[str, Any]:
        return {"particles_in_bucket": 0, "mass_in_bucket_kg": 0.0, "fill_factor": 0.0, "volumetric_fill": 0.0,
                "penetrating": False, "reached": False, "success": False, "overloaded": False, "spilled": 0,
                "physics_error": True, "elapsed_s": self.sim.elapsed_s,
                "tip_to_pile_m": float("nan"), "tip_to_terminal_m": float("nan"),
                "lift_torque_nm": float("nan"), "tilt_torque_nm": float("nan"),
                "reward_progress": 0.0, "reward_mass": 0.0, "world": copy.deepcopy(self.world)}


class EndedEpisodeGuard(gym.Wrapper):
    """Refuses ``step`` once the episode has ended (terminated or truncated) until ``reset``, as Gymnasium's API
    asks: stepping on would keep simulating past the terminal point and pay its bonus again.

    Raises:
        gymnasium.error.ResetNeeded: from ``step`` after the end.
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self._ended = False

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict]:
        self._ended = False
        return self.env.reset(**kwargs)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        if self._ended:
            raise gym.error.ResetNeeded("step() after the episode ended (terminated or truncated); call reset() first")
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._ended = bool(terminated or truncated)
        return obs, reward, terminated, truncated, info


def make_scoop_env(config: ScoopConfig | None = None, render_mode: str | None = None,
                   **overrides: Any) -> gym.Env:
    """The entry point of every ``autoscoop/`` id (``gym.make("autoscoop/Scoop-v1", ...)``): the env inside a
    ``TimeLimit`` of ``env.max_episode_s``, inside an :class:`EndedEpisodeGuard`."""
    env = ScoopEnv(config=config, render_mode=render_mode, **overrides)
    return EndedEpisodeGuard(TimeLimit(env, max_episode_steps=env.config.max_episode_steps))
