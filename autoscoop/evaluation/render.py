"""Off-screen video frames of an episode, more of them than there are control steps.

A control step (0.25 s) is several physics steps. :class:`FrameCapture` watches those physics steps
(a substep observer of the simulator) and renders the scene every few of them, so a video shows real
simulation states at ``fps`` frames per simulated second. MuJoCo's ``mj_step`` called ``n`` times is
exactly one call with ``nstep = n``, so the episode is the same as without capture (a test checks it).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from autoscoop.core.phases import phase_now
from autoscoop.sim.glbackend import INSTALL_HINT

FRAME_SIZE = (768, 432)
"""Width and height of rendered frames, pixels (16:9, both multiples of 16 for video encoders)."""
CAMERA = "side"
"""The scene's camera (``machines/komodo/scene.xml``) that frames the loader and the pile from the side."""


def frame_interval_steps(timestep_s: float, fps: float) -> int:
    """Physics steps between two frames for at least ``fps`` frames per simulated second."""
    return max(1, int(np.floor(1.0 / (fps * timestep_s) + 1e-9)))


class FrameCapture(gym.Wrapper):
    """Renders the scene every few physics steps while the wrapped environment runs.

    Frames collect in :attr:`frames` (RGB arrays) with their simulated times in :attr:`times_s`;
    each is labelled with the time, the phase and the load in the bucket.

    Args:
        env: an autoscoop environment (``make_scoop_env``), possibly wrapped.
        fps: frames per simulated second, at least; the exact rate is :attr:`fps`.
        size: (width, height) of a frame, pixels.
        label: draw the time, phase and load on each frame.

    Raises:
        RuntimeError: if no OpenGL context can be made (the message says what to install).
    """

    def __init__(self, env: gym.Env, fps: float = 16.0, size: tuple[int, int] = FRAME_SIZE,
                 label: bool = True) -> None:
        super().__init__(env)
        import mujoco  # noqa: PLC0415 - only rendering needs the GL side of mujoco

        self.sim = env.unwrapped.sim
        timestep = float(self.sim.model.opt.timestep)
        self.interval = frame_interval_steps(timestep, fps)
        self.fps = 1.0 / (self.interval * timestep)
        try:
            self._renderer = mujoco.Renderer(self.sim.model, height=size[1], width=size[0])
        except Exception as error:  # the GL backends raise a variety of errors
            raise RuntimeError(f"cannot render off-screen ({error}); {INSTALL_HINT}") from error
        self.label = label
        self.frames: list[np.ndarray] = []
        self.times_s: list[float] = []
        self._since_frame = 0
        self._penetrated = False
        self._penetrating = False
        self.sim.add_substep_observer(self._after_physics_step)  # detached by close()

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        obs, info = self.env.reset(seed=seed, options=options)
        self.frames, self.times_s = [], []
        self._since_frame = 0
        self._penetrated = self._penetrating = bool(info.get("penetrating", False))
        self._capture()
        return obs, info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._penetrating = bool(info.get("penetrating", False))
        self._penetrated |= self._penetrating
        if (terminated or truncated) and self._since_frame:
            self._capture()  # the final state, even off the frame grid
        return obs, reward, terminated, truncated, info

    def close(self) -> None:
        self.sim.remove_substep_observer(self._after_physics_step)
        self._renderer.close()
        super().close()

    def _after_physics_step(self) -> None:
        self._since_frame += 1
        if self._since_frame == self.interval:
            self._capture()

    def _capture(self) -> None:
        self._since_frame = 0
        self._renderer.update_scene(self.sim.data, camera=CAMERA)
        frame = self._renderer.render()
        if self.label:
            inside = self.sim.particles_in_bucket()
            mass = float(self.sim.particle_masses[inside].sum())
            phase = phase_now(self._penetrated, self._penetrating)
            frame = label_frame(frame, f"t = {self.sim.elapsed_s:4.2f} s   {phase:<8}   "
                                       f"bucket: {int(inside.sum()):2d} particles, {mass:3.1f} kg")
        self.frames.append(frame)
        self.times_s.append(self.sim.elapsed_s)


def label_frame(frame: np.ndarray, text: str) -> np.ndarray:
    """The frame with ``text`` on a dark band along its top edge."""
    from PIL import Image, ImageDraw, ImageFont  # noqa: PLC0415 - Pillow comes with imageio

    image = Image.fromarray(frame)
    draw = ImageDraw.Draw(image)
    size = max(12, image.height // 24)
    try:
        font: Any = ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1 has one fixed-size default font
        font = ImageFont.load_default()
    draw.rectangle([0, 0, image.width, int(size * 1.6)], fill=(20, 20, 20))
    draw.text((int(size * 0.5), int(size * 0.3)), text, fill=(240, 240, 240), font=font)
    return np.asarray(image)


def render_episode(policy: Any, config: Any, seed: int, fps: float = 16.0,
                   size: tuple[int, int] = FRAME_SIZE) -> tuple[FrameCapture, Any, Any]:
    """Run one episode of ``policy`` while filming it.

    Args:
        policy: an ``autoscoop.core.policy.Policy``.
        config: the ``ScoopConfig`` of the scene.
        seed: the episode's seed (the same seed as in ``autoscoop eval`` gives the same episode).
        fps: frames per simulated second, at least.
        size: (width, height) of the frames, pixels.

    Returns:
        (the capture, holding ``frames``, ``times_s`` and ``fps``; the episode's record,
        an ``EpisodeRecord``; its ``EpisodeOutcome``). The capture is closed.
    """
    from autoscoop.envs.rollout import rollout  # noqa: PLC0415 - keeps this module light to import
    from autoscoop.envs.scoop import make_scoop_env  # noqa: PLC0415
    from autoscoop.evaluation.recorder import EpisodeRecorder  # noqa: PLC0415

    capture = FrameCapture(make_scoop_env(config), fps=fps, size=size)
    recorder = EpisodeRecorder(capture, {"policy": policy.name, "source": "video"})
    try:
        result = rollout(policy, recorder, seed)
        recorder.record.meta["outcome"] = result.as_dict()
    finally:
        recorder.close()
    return capture, recorder.record, result
