"""Off-screen video frames of a shift: the scene filmed from the side every few physics steps, labelled with the
time, the load in the bucket and the mass delivered so far."""

from __future__ import annotations

from typing import Any

import numpy as np

from autoscoop.evaluation.render import CAMERA, FRAME_SIZE, frame_interval_steps, label_frame
from autoscoop.sim.glbackend import INSTALL_HINT

SHIFT_FPS = 4.0
"""Frames per simulated second of a shift's video (a 15-cycle shift lasts about 7 minutes simulated)."""


class ShiftFilm:
    """Renders a shift's scene every few physics steps while it is attached to the shift's simulator.

    Args:
        fps: frames per simulated second, at least; the exact rate is :attr:`fps` once attached.
        size: (width, height) of a frame, pixels.
    """

    def __init__(self, fps: float = SHIFT_FPS, size: tuple[int, int] = FRAME_SIZE) -> None:
        self.requested_fps, self.size = fps, size
        self.fps = fps
        self.frames: list[np.ndarray] = []
        self._sim: Any = None
        self._renderer: Any = None
        self._interval = 1
        self._since_frame = 0

    def attach(self, sim: Any) -> None:
        """Film ``sim`` (a :class:`~autoscoop.sim.shift_sim.ShiftSim`) from now on.

        Raises:
            RuntimeError: if no OpenGL context can be made (the message says what to install).
        """
        import mujoco  # noqa: PLC0415 - only rendering needs the GL side of mujoco

        timestep = float(sim.model.opt.timestep)
        self._interval = frame_interval_steps(timestep, self.requested_fps)
        self.fps = 1.0 / (self._interval * timestep)
        try:
            self._renderer = mujoco.Renderer(sim.model, height=self.size[1], width=self.size[0])
        except Exception as error:  # the GL backends raise a variety of errors
            raise RuntimeError(f"cannot render off-screen ({error}); {INSTALL_HINT}") from error
        self._sim = sim
        sim.add_substep_observer(self._after_physics_step)

    def detach(self) -> None:
        """Stop filming and free the renderer."""
        if self._sim is not None:
            self._sim.remove_substep_observer(self._after_physics_step)
            self._renderer.close()
            self._sim = None

    def _after_physics_step(self) -> None:
        self._since_frame += 1
        if self._since_frame >= self._interval:
            self._since_frame = 0
            sim = self._sim
            self._renderer.update_scene(sim.data, camera=CAMERA)
            inside = sim.particles_in_bucket()
            delivered = float(sim.particle_masses[sim.delivered].sum())
            text = (f"t = {len(self.frames) / self.fps:6.1f} s   bucket: {int(inside.sum()):2d} particles   "
                    f"delivered: {delivered:5.1f} kg")
            self.frames.append(label_frame(self._renderer.render(), text))
