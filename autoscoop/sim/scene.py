"""The scooping scene in MuJoCo: build it from a config, reset it, drive it, read it by name.

World frame = pile frame: x forward from the pile's toe, y left, z up from the ground, metres.
This module owns the simulator; the task (state, reward, episode) lives in ``autoscoop.envs``.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

import mujoco
import numpy as np

from autoscoop.core import kinematics
from autoscoop.core.config import PileConfig, ScoopConfig
from autoscoop.core.machine import SCENE_FILE
from autoscoop.sim.pile import pile_layout

WHEELS = ("wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr")
WHEEL_RADIUS_M = kinematics.MACHINE.wheels.radius_m
"""The machine's wheel radius, m (drive speed = wheel speed * radius)."""
INSTABILITY_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_CNSTRFULL,
    mujoco.mjtWarning.mjWARN_CONTACTFULL,
)
PARTICLE_CONTYPE, PARTICLE_CONAFFINITY = 2, 7
"""Collision bits: ground 1, particles 2, robot 4. Particles touch all three; the robot is not
tested against itself."""


def scene_path() -> str:
    """Path of the machine's scene (``scene.xml`` beside its MJCF, e.g. ``machines/komodo/scene.xml``: ground,
    light, camera and solver settings; it includes the machine's MJCF)."""
    return str(kinematics.MACHINE.mjcf_path().with_name(SCENE_FILE))


SETTLE_EXTRA_S = 3.0
"""Longest extra time a new pile may take to come to rest after ``pile.settle_s``."""
PRESCOOP_HEIGHT_WEIGHT = 0.5
"""An earlier scoop takes the face's particles in order of distance behind the face plus this times their height."""
PARKED_X_M, PARKED_Y_M = -4.0, 3.0
"""Where particles taken by an earlier scoop rest: behind the robot and to its side, out of every reading."""
SETTLED_BANK_SIZE = 256
"""Most settled piles one scene keeps (a randomised world settles a pile per angle and earlier scoop)."""
SLEEP_TOLERANCE = 0.03
"""Bodies slower than this (MuJoCo's sleep_tolerance) fall asleep; a resting pile then costs almost nothing."""


def contact_time_constant_s(timestep_s: float) -> float:
    """Contact stiffness time constant: MuJoCo's default 0.02 s, never below two physics steps."""
    return max(0.02, 2.0 * timestep_s)


def build_spec(config: ScoopConfig) -> mujoco.MjSpec:
    """The scene as an editable MjSpec: loader, ground and the pile's particles, limits from the config."""
    spec = mujoco.MjSpec.from_file(scene_path())
    spec.option.timestep = config.env.timestep_s
    spec.option.enableflags |= int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    spec.option.sleep_tolerance = SLEEP_TOLERANCE
    robot = config.robot
    spec.actuator("lift").forcerange = [-robot.lift_torque_limit_nm, robot.lift_torque_limit_nm]
    spec.actuator("tilt").forcerange = [-robot.tilt_torque_limit_nm, robot.tilt_torque_limit_nm]
    spec.actuator("lift").ctrlrange = [-robot.lift_speed_radps, robot.lift_speed_radps]
    spec.actuator("tilt").ctrlrange = [-robot.tilt_speed_radps, robot.tilt_speed_radps]
    for wheel in WHEELS:
        spec.actuator(wheel).forcerange = [-robot.wheel_torque_limit_nm, robot.wheel_torque_limit_nm]
        spec.geom(wheel).friction = [robot.ground_friction, 0.005, 0.0001]
    for geom in spec.geoms:
        if geom.name.startswith("bucket_"):
            # priority: the bucket's friction, not the larger of the two, governs bucket-particle contacts
            geom.priority = 1
            geom.friction = [robot.bucket_friction, 0.005, 0.0001]
    pile = config.pile
    for i, centre in enumerate(pile_layout(pile)):
        body = spec.worldbody.add_body(name=f"particle_{i:03d}", pos=centre.tolist())
        add_particle_joints(body, f"particle_{i:03d}", centre, pile.rolling)
        body.add_geom(name=f"particle_{i:03d}", type=mujoco.mjtGeom.mjGEOM_SPHERE,
                      size=[pile.radius_m, 0, 0], mass=pile.particle_mass_kg,
                      contype=PARTICLE_CONTYPE, conaffinity=PARTICLE_CONAFFINITY, condim=3,
                      friction=[pile.friction, 0.0, 0.0], rgba=[0.55, 0.45, 0.35, 1.0])
    time_constant = contact_time_constant_s(config.env.timestep_s)
    for geom in spec.geoms:
        geom.solref = [time_constant, 1.0]
    return spec


def add_particle_joints(body: mujoco.MjsBody, name: str, centre: np.ndarray, rolling: bool) -> None:
    """Give a particle its degrees of freedom; ``qpos`` then holds its world position first.

    Rolling: a free joint (position, then orientation quaternion). Not rolling: three slide joints
    along world x, y, z (named ``name``, ``name_y``, ``name_z``) whose ``ref`` is the body's
    position, so the three ``qpos`` entries are the particle's world position.
    """
    if rolling:
        body.add_freejoint(name=name)
        return
    for k, (suffix, axis) in enumerate((("", [1, 0, 0]), ("_y", [0, 1, 0]), ("_z", [0, 0, 1]))):
        body.add_joint(name=name + suffix, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis, ref=float(centre[k]))


def compile_scene(config: ScoopConfig, add_bodies: Callable[[mujoco.MjSpec], None] | None = None) -> mujoco.MjModel:
    """Compile the scene (``add_bodies`` may add to its spec first: a shift's hopper); rolling particles get their
    spin damped.

    Gravel is angular and does not roll like marbles. MuJoCo's rolling friction (condim 6) would
    triple the contact rows; damping the particles' three rotational degrees of freedom gives the
    resistance at no cost per contact (the integrator treats it implicitly). With
    ``pile.rolling: false`` the particles cannot turn at all (three slide joints each): the limit of
    that resistance, and a faster scene (fewer degrees of freedom in the contact solve), but not the
    one the shipped policy and the scripted controller are tuned for.
    """
    spec = build_spec(config)
    if add_bodies is not None:
        add_bodies(spec)
    model = spec.compile()
    if config.pile.rolling:
        for i in range(config.pile.n_particles):
            dof = model.jnt_dofadr[model.joint(f"particle_{i:03d}").id]
            model.dof_damping[dof + 3:dof + 6] = config.pile.rolling_damping_nms
    return model


class ScoopSim:
    """The loader and the pile in MuJoCo, with accessors by name.

    Args:
        config: scene configuration (robot limits, pile, physics step).
    """

    def __init__(self, config: ScoopConfig) -> None:
        self.config = config
        self.model = self.compile_model(config)
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.n_particles = config.pile.n_particles
        self._particle_bodies = np.array([m.body(f"particle_{i:03d}").id for i in range(self.n_particles)], dtype=int)
        self._particle_qpos = np.array([m.joint(f"particle_{i:03d}").qposadr[0] for i in range(self.n_particles)], dtype=int)
        self._particle_mass = m.body_mass[self._particle_bodies].copy()
        self._bucket = m.body("bucket").id
        self._chassis = m.body("chassis").id
        self._tip = m.site("tip").id
        self._bucket_joint = m.site("bucket_joint").id
        self._root_qpos = m.joint("root").qposadr[0]
        self._lift_qpos = m.joint("lift").qposadr[0]
        self._tilt_qpos = m.joint("tilt").qposadr[0]
        self._lift_act = m.actuator("lift").id
        self._tilt_act = m.actuator("tilt").id
        self._wheel_acts = np.array([m.actuator(w).id for w in WHEELS], dtype=int)
        self._wheel_dofs = np.array([m.joint(w).dofadr[0] for w in WHEELS], dtype=int)
        self._lift_act_state = m.actuator_actadr[self._lift_act]
        self._tilt_act_state = m.actuator_actadr[self._tilt_act]
        self._particle_geoms = np.array([m.geom(f"particle_{i:03d}").id for i in range(self.n_particles)], dtype=int)
        self._wheel_geoms = np.array([m.geom(w).id for w in WHEELS], dtype=int)
        self._bucket_geoms = np.array([g for g in range(m.ngeom) if m.geom(g).name.startswith("bucket_")], dtype=int)
        self._particle_inertia_per_kg = m.body_inertia[self._particle_bodies] / m.body_mass[self._particle_bodies, None]
        self.time_origin_s = 0.0
        self._settled: dict[tuple, mujoco.MjData] = {}
        self.variant = 0
        self._pile = config.pile
        self._substep_observers: list[Callable[[], None]] = []
        self.odometry_window_steps = config.sensor.odometry_window_steps
        # the mean wheel speed (rad/s) of the physics steps before the last, newest last: the odometry
        # averages it with the present one over sensor.odometry_window_steps
        self._wheel_speed_history: deque[float] = deque(maxlen=self.odometry_window_steps - 1)

    def compile_model(self, config: ScoopConfig) -> mujoco.MjModel:
        """The compiled scene this simulator runs (a subclass may add bodies: :func:`compile_scene`)."""
        return compile_scene(config)

    # ---------------------------------------------------------------- reset and stepping
    def reset(self, rng: np.random.Generator | None = None, *, pile: PileConfig | None = None,
              start_gap_m: float | None = None, prescoop_particles: int | None = None) -> None:
        """Start an episode: a settled pile (toe at x = 0), the robot's tip ``start_gap_m`` before it.

        The pile is one of ``pile.variants`` jittered layouts, each settled once (until it rests) and
        then restored by copying the whole simulator state, its sleeping pile included: a resting
        pile costs almost nothing to simulate until the bucket touches it. The start gap varies by
        up to ``robot.start_gap_jitter_m``. The episode clock (:attr:`elapsed_s`) starts here.

        Args:
            rng: the episode's generator (variant, then start-gap jitter).
            pile: this episode's pile (a randomised world: its angle), instead of the config's; its
                particle count and radius must be the compiled scene's.
            start_gap_m: this episode's start gap, m, instead of ``robot.start_gap_m``.
            prescoop_particles: the pile was scooped once before: this many particles of its face were
                taken away, the lowest first, and the rest settled again (:meth:`prescoop`).
        """
        rng = rng if rng is not None else np.random.default_rng()
        variant = int(rng.integers(self.config.pile.variants))
        self.variant = variant
        self._pile = self.pile_of_variant(variant) if pile is None else pile
        key: tuple = (variant,) if pile is None and prescoop_particles is None else (
            variant, round(self._pile.angle_deg, 3), prescoop_particles)
        if key not in self._settled:
            if len(self._settled) >= SETTLED_BANK_SIZE:  # forget the oldest settled pile
                self._settled.pop(next(iter(self._settled)))
            self._settled[key] = self._settle(variant, self._pile, prescoop_particles)
        mujoco.mj_copyData(self.data, self.model, self._settled[key])
        jitter = self.config.robot.start_gap_jitter_m
        if jitter > 0:
            self.data.qpos[self._root_qpos] += rng.uniform(-jitter, jitter)
        if start_gap_m is not None:
            self.data.qpos[self._root_qpos] -= start_gap_m - self.config.robot.start_gap_m
        mujoco.mj_kinematics(self.model, self.data)  # positions only: keeps the pile asleep
        self.restart_clock()

    def restart_clock(self) -> None:
        """Start the episode clock (:attr:`elapsed_s`) and the odometry's window afresh, here."""
        self.time_origin_s = float(self.data.time)
        self._wheel_speed_history.clear()

    def pile_of_variant(self, variant: int) -> PileConfig:
        """The pile settings of one variant: ``pile.angle_mix_deg`` in turn, if given."""
        mix = self.config.pile.angle_mix_deg
        return self.config.pile.replace(angle_deg=mix[variant % len(mix)]) if mix else self.config.pile

    @property
    def pile_angle_deg(self) -> float:
        """Face slope of the pile in the current episode, degrees."""
        return self._pile.angle_deg

    def apply_parameters(self, config: ScoopConfig) -> None:
        """Write one episode's physical parameters into the compiled model (no recompiling): particle
        mass and friction, wheel-ground and bucket friction, actuator torque and speed limits.

        ``config`` must describe the same scene (particle count and radius) as the one compiled; a
        randomised world (:mod:`autoscoop.sim.world`) calls this before each episode's reset.
        """
        if config.pile.n_particles != self.n_particles:
            raise ValueError(f"apply_parameters: {config.pile.n_particles} particles, the scene has {self.n_particles}")
        m, robot, pile = self.model, config.robot, config.pile
        m.body_mass[self._particle_bodies] = pile.particle_mass_kg
        m.body_inertia[self._particle_bodies] = self._particle_inertia_per_kg * pile.particle_mass_kg
        self._particle_mass = m.body_mass[self._particle_bodies].copy()
        m.geom_friction[self._particle_geoms, 0] = pile.friction
        m.geom_friction[self._wheel_geoms, 0] = robot.ground_friction
        m.geom_friction[self._bucket_geoms, 0] = robot.bucket_friction
        m.actuator_forcerange[self._lift_act] = [-robot.lift_torque_limit_nm, robot.lift_torque_limit_nm]
        m.actuator_forcerange[self._tilt_act] = [-robot.tilt_torque_limit_nm, robot.tilt_torque_limit_nm]
        m.actuator_forcerange[self._wheel_acts] = [-robot.wheel_torque_limit_nm, robot.wheel_torque_limit_nm]
        m.actuator_ctrlrange[self._lift_act] = [-robot.lift_speed_radps, robot.lift_speed_radps]
        m.actuator_ctrlrange[self._tilt_act] = [-robot.tilt_speed_radps, robot.tilt_speed_radps]

    def _settle(self, variant: int, pile: PileConfig, prescoop_particles: int | None = None) -> mujoco.MjData:
        """Build pile ``variant`` (its own jitter) of ``pile``'s angle, let it settle under gravity
        (scooped once before: ``prescoop_particles`` taken), return the state."""
        m, d, cfg = self.model, self.data, self.config
        mujoco.mj_resetData(m, d)
        self.set_start_pose(cfg.robot.start_gap_m)
        centres = pile_layout(pile, np.random.default_rng([variant, 20211]))
        for index, centre in enumerate(centres):
            self._place_particle(index, centre)
        mujoco.mj_forward(m, d)
        self._settle_pile(cfg.pile.settle_s)
        if prescoop_particles is not None:
            self.prescoop(pile.angle_deg, prescoop_particles)
            self._settle_pile(cfg.pile.settle_s)
        settled = mujoco.MjData(m)
        mujoco.mj_copyData(settled, m, d)
        return settled

    def _settle_pile(self, settle_s: float) -> None:
        """Step ``settle_s``, then on until the pile rests (at most :data:`SETTLE_EXTRA_S` more)."""
        m, d = self.model, self.data
        step = m.opt.timestep
        mujoco.mj_step(m, d, nstep=int(round(settle_s / step)))
        robot_bodies = m.nbody - self.n_particles
        for _ in range(int(round(SETTLE_EXTRA_S / step))):
            if d.nbody_awake <= robot_bodies:
                break
            mujoco.mj_step(m, d)

    def prescoop(self, angle_deg: float, particles: int) -> int:
        """Take away what an earlier scoop took: ``particles`` particles of the pile's face, those nearest
        its toe first (the least distance behind the face line, the slope ``angle_deg`` through the toe,
        plus half their height: a bucket cuts in low and curls up); they are parked at rest far behind the
        robot. Returns how many were taken.
        """
        positions = self.particle_positions.copy()
        radius = self._pile.radius_m
        height = positions[:, 2] - radius
        behind_face = positions[:, 0] - radius - height / math.tan(math.radians(angle_deg))
        order = np.argsort(behind_face + PRESCOOP_HEIGHT_WEIGHT * height, kind="stable")
        taken = order[:max(0, min(int(particles), self.n_particles - 1))]
        for k, index in enumerate(taken):
            self.set_particle(int(index), np.array([PARKED_X_M - 3 * radius * k, PARKED_Y_M, radius]))
        mujoco.mj_forward(self.model, self.data)
        return len(taken)

    def command(self, forward_speed_mps: float, lift_rate_radps: float, tilt_rate_radps: float) -> None:
        """Set the actuator inputs: wheel speed for a forward speed, and the servo setpoints' rates."""
        d = self.data
        d.ctrl[self._wheel_acts] = forward_speed_mps / WHEEL_RADIUS_M
        d.ctrl[self._lift_act] = lift_rate_radps
        d.ctrl[self._tilt_act] = tilt_rate_radps

    def step(self, n_steps: int) -> None:
        """Advance the physics by ``n_steps`` steps: in C, one call, unless substep observers are attached
        (:meth:`add_substep_observer`), which are then called after every step, in the order they were added."""
        history = self._wheel_speed_history.maxlen or 0  # steps the odometry looks back
        if not self._substep_observers:
            # the last steps one by one, to remember the wheel speed the odometry averages over
            if n_steps > history:
                mujoco.mj_step(self.model, self.data, nstep=n_steps - history)
            for _ in range(min(n_steps, history)):
                self._wheel_speed_history.append(self._wheel_speed_radps())
                mujoco.mj_step(self.model, self.data)
            return
        for _ in range(n_steps):
            if history:
                self._wheel_speed_history.append(self._wheel_speed_radps())
            mujoco.mj_step(self.model, self.data)
            for observer in tuple(self._substep_observers):
                observer()

    # ---------------------------------------------------------------- pose and observers (public API)
    def set_pose(self, chassis_x_m: float, lift_rad: float, tilt_rad: float) -> None:
        """Place the robot: chassis upright on the ground with its centre at world x ``chassis_x_m`` (y = 0,
        facing +x), arm at ``lift_rad`` and bucket at ``tilt_rad``, both servos holding those angles.

        Writes positions only (velocities are left as they are); call ``mujoco.mj_forward`` or step
        before reading derived quantities.
        """
        d = self.data
        d.qpos[self._root_qpos:self._root_qpos + 7] = [chassis_x_m, 0.0, kinematics.CHASSIS_CENTRE_HEIGHT_M,
                                                       1, 0, 0, 0]
        d.qpos[self._lift_qpos] = lift_rad
        d.qpos[self._tilt_qpos] = tilt_rad
        d.act[self._lift_act_state] = lift_rad
        d.act[self._tilt_act_state] = tilt_rad

    def set_start_pose(self, start_gap_m: float) -> None:
        """Place the robot at its start pose (``robot.start_lift_rad``, ``robot.start_tilt_rad``) with its tip
        ``start_gap_m`` before the pile's toe at x = 0 (:meth:`set_pose`: positions only)."""
        lift, tilt = self.config.robot.start_lift_rad, self.config.robot.start_tilt_rad
        self.set_pose(-start_gap_m - float(kinematics.arm_pose(lift, tilt).tip[0]), lift, tilt)

    def add_substep_observer(self, observer: Callable[[], None]) -> None:
        """Call ``observer()`` after every physics step from now on (a load cell averaging its readings,
        a recorder, a pacer). Several may be attached; while any is, :meth:`step` runs steps one by one."""
        self._substep_observers.append(observer)

    def remove_substep_observer(self, observer: Callable[[], None]) -> None:
        """Stop calling ``observer`` (no error if it was not attached)."""
        if observer in self._substep_observers:
            self._substep_observers.remove(observer)

    @property
    def substep_observers(self) -> tuple[Callable[[], None], ...]:
        """The observers attached now, in call order."""
        return tuple(self._substep_observers)

    def instability_count(self) -> int:
        """How many times MuJoCo has flagged an instability (bad acceleration, full buffers) since reset."""
        return int(sum(self.data.warning[w].number for w in INSTABILITY_WARNINGS))

    def is_finite(self) -> bool:
        """Whether positions and velocities are all finite."""
        # a sum is NaN or infinite when any term is (or overflows: a diverged state as well)
        return bool(np.isfinite(self.data.qpos.sum() + self.data.qvel.sum()))

    # ---------------------------------------------------------------- named readings
    @property
    def elapsed_s(self) -> float:
        """Seconds since the episode's start (after settling)."""
        return float(self.data.time) - self.time_origin_s

    @property
    def lift_rad(self) -> float:
        """Measured lift angle (potentiometer), rad; larger lowers the arm."""
        return float(self.data.qpos[self._lift_qpos])

    @property
    def tilt_rad(self) -> float:
        """Measured tilt angle (potentiometer), rad; larger tips the cutting edge down."""
        return float(self.data.qpos[self._tilt_qpos])

    @property
    def lift_setpoint_rad(self) -> float:
        """Where the lift servo is heading now (its integrated setpoint), rad."""
        return float(self.data.act[self._lift_act_state])

    @property
    def tilt_setpoint_rad(self) -> float:
        """Where the tilt servo is heading now (its integrated setpoint), rad."""
        return float(self.data.act[self._tilt_act_state])

    def _wheel_speed_radps(self) -> float:
        """The four wheels' mean angular speed now, rad/s."""
        return float(self.data.qvel[self._wheel_dofs].mean())

    @property
    def odometry_speed_mps(self) -> float:
        """Forward speed from wheel odometry, m/s: the wheels' mean speed over the last
        ``sensor.odometry_window_steps`` physics steps (their angle change over that time, as an encoder
        counts it; fewer just after a reset) times the wheel radius. Slip makes it differ from truth.

        The wheels' velocity servos ring at the physics step while the wheels push into the pile (the
        instantaneous speed alternates between about +0.2 and -0.05 m/s about a mean near 0.08), so
        a window of one step reads a speed that depends on which step a reading lands on; two steps
        or more average the ringing out."""
        history = self._wheel_speed_history
        mean = (self._wheel_speed_radps() + sum(history)) / (1 + len(history))
        return float(mean * WHEEL_RADIUS_M)

    @property
    def lift_torque_nm(self) -> float:
        """Actuator torque at the lift joint, N*m (sensor ``lift_torque``)."""
        return float(self.data.sensor("lift_torque").data[0])

    @property
    def tilt_torque_nm(self) -> float:
        """Actuator torque at the tilt (bucket) joint, N*m (sensor ``tilt_torque``)."""
        return float(self.data.sensor("tilt_torque").data[0])

    @property
    def tip_world(self) -> np.ndarray:
        """Bucket cutting edge in the world frame, (3,) m."""
        return self.data.site_xpos[self._tip].copy()

    @property
    def bucket_joint_world(self) -> np.ndarray:
        """Tilt joint in the world frame, (3,) m."""
        return self.data.site_xpos[self._bucket_joint].copy()

    @property
    def chassis_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Chassis centre position (3,) m and rotation matrix (3, 3) in the world frame."""
        return self.data.xpos[self._chassis].copy(), self.data.xmat[self._chassis].reshape(3, 3).copy()

    @property
    def particle_positions(self) -> np.ndarray:
        """Particle centres in the world frame, (n, 3) m."""
        return self.data.xpos[self._particle_bodies]

    @property
    def particle_masses(self) -> np.ndarray:
        """Mass of each particle, (n,) kg."""
        return self._particle_mass

    @property
    def bucket_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Bucket frame origin (the tilt joint) (3,) m and rotation matrix (3, 3) in the world frame;
        bucket frame: x toward the cutting edge, y across, z toward the mouth."""
        return self.data.xpos[self._bucket].copy(), self.data.xmat[self._bucket].reshape(3, 3).copy()

    def bucket_to_world(self, point_bucket_m: np.ndarray) -> np.ndarray:
        """A point given in the bucket frame, (3,) m, expressed in the world frame, (3,) m."""
        origin, rotation = self.bucket_pose
        return origin + rotation @ np.asarray(point_bucket_m, dtype=float)

    def particles_in_bucket_frame(self) -> np.ndarray:
        """Particle centres in the bucket frame (x to the cutting edge, y across, z toward the mouth), (n, 3) m."""
        origin, rotation = self.bucket_pose
        return (self.particle_positions - origin) @ rotation

    def particles_in_bucket(self) -> np.ndarray:
        """(n,) mask of particles whose centre lies inside the bucket's volume (in the bucket's own frame)."""
        return kinematics.inside_bucket(self.particles_in_bucket_frame())


    def set_particle(self, index: int, position: np.ndarray) -> None:
        """Teleport one particle (at rest) to a world position; for scenes with sleeping disabled."""
        self._place_particle(index, position)
        body = self._particle_bodies[index]
        dof = self.model.body_dofadr[body]
        self.data.qvel[dof:dof + self.model.body_dofnum[body]] = 0.0

    def _place_particle(self, index: int, position: np.ndarray) -> None:
        """Write a particle's world position (and, if it rolls, the identity orientation) into ``qpos``."""
        adr = self._particle_qpos[index]
        if self.config.pile.rolling:
            self.data.qpos[adr:adr + 7] = [*position, 1, 0, 0, 0]
        else:
            self.data.qpos[adr:adr + 3] = position

