"""Manual control: a person drives, lifts and tilts with the keyboard in MuJoCo's viewer.

:class:`TeleopKeys` turns key presses into the environment's actions and needs no display (tests
use it directly); :func:`run_session` runs episodes in real time in a viewer (``mujoco.viewer``'s
passive viewer, or any object with the same few methods) and saves each finished episode as an
episode record (:mod:`autoscoop.envs.records`), like evaluation does.

A key press moves what the person asks for (forward speed, lift angle, tilt angle) by one step;
the speed is held until changed, as on the real robot's remote control. Each control step sends the
action that moves the environment's targets to what is asked, so the environment's own limits
(servo speed, ranges) apply as they do to every controller.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from autoscoop.core.state import CommandLimits, advance_targets
from autoscoop.envs.rollout import rollout

# GLFW key codes, which MuJoCo's viewer passes to its key callback.
KEY_SPACE, KEY_ENTER = 32, 257
KEY_RIGHT, KEY_LEFT, KEY_DOWN, KEY_UP = 262, 263, 264, 265
KEY_PAGE_UP, KEY_PAGE_DOWN = 266, 267
KEY_KP_2, KEY_KP_3, KEY_KP_4, KEY_KP_5, KEY_KP_6, KEY_KP_8, KEY_KP_9 = 322, 323, 324, 325, 326, 328, 329
KEY_KP_ENTER = 335

BINDINGS: dict[str, tuple[tuple[int, ...], str, str]] = {
    # command: (keys, key names, what it does)
    "forward": ((KEY_UP, KEY_KP_8), "Up", "drive: faster forward"),
    "backward": ((KEY_DOWN, KEY_KP_2), "Down", "drive: faster backward"),
    "stop": ((KEY_SPACE, KEY_KP_5), "Space", "drive: stop"),
    "raise": ((KEY_PAGE_UP, KEY_KP_9), "PgUp", "lift: raise the arm"),
    "lower": ((KEY_PAGE_DOWN, KEY_KP_3), "PgDn", "lift: lower the arm"),
    "curl": ((KEY_LEFT, KEY_KP_4), "Left", "tilt: curl (cutting edge up)"),
    "dump": ((KEY_RIGHT, KEY_KP_6), "Right", "tilt: tip (cutting edge down)"),
    "enter": ((KEY_ENTER, KEY_KP_ENTER), "Enter", "end the episode and save it / start the next"),
}
"""Arrow keys, Page Up/Down, Space and Enter (or the numeric keypad): keys MuJoCo's passive viewer
leaves alone, unlike letters, which toggle its rendering options."""


@dataclass(frozen=True)
class TeleopSteps:
    """How far one key press moves what is asked for."""

    speed_mps: float = 0.025
    """forward speed change per press, m/s (4 presses from stop to the 0.1 m/s limit)."""
    lift_rad: float = 0.04
    """lift angle change per press, rad."""
    tilt_rad: float = 0.10
    """tilt angle change per press, rad."""


class TeleopKeys:
    """Key presses in, actions out; safe to press from the viewer's thread while the loop reads actions.

    Args:
        limits: the commanded targets' limits (as the environment's).
        steps: how far one press moves each target.
    """

    def __init__(self, limits: CommandLimits | None = None, steps: TeleopSteps | None = None) -> None:
        self.limits = limits or CommandLimits()
        self.steps = steps or TeleopSteps()
        self._by_key = {key: command for command, (keys, _, _) in BINDINGS.items() for key in keys}
        self._lock = threading.Lock()
        self.reset(np.zeros(3))

    def reset(self, targets: np.ndarray) -> None:
        """Start an episode whose targets (speed m/s, lift rad, tilt rad) are ``targets``."""
        with self._lock:
            self._targets = np.asarray(targets, dtype=float).copy()
            self._asked = self._targets.copy()
            self.enter_pressed = False

    @property
    def asked(self) -> np.ndarray:
        """What the person asks for now: (speed m/s, lift rad, tilt rad)."""
        with self._lock:
            return self._asked.copy()

    def press(self, key: int) -> str | None:
        """Handle one key press (a GLFW key code); return the command it gave, or ``None``."""
        command = self._by_key.get(key)
        if command is None:
            return None
        s = self.steps
        change = {"forward": (0, s.speed_mps), "backward": (0, -s.speed_mps), "raise": (1, -s.lift_rad),
                  "lower": (1, s.lift_rad), "curl": (2, -s.tilt_rad), "dump": (2, s.tilt_rad)}
        with self._lock:
            if command == "stop":
                self._asked[0] = 0.0
            elif command == "enter":
                self.enter_pressed = True
            else:
                index, delta = change[command]
                self._asked[index] += delta
            self._asked = np.clip(self._asked, self.limits.low, self.limits.high)
        return command

    def next_action(self) -> np.ndarray:
        """The action (drive, lift, tilt in [-1, 1]) that moves the targets to what is asked."""
        with self._lock:
            span = self.limits.high - self.limits.low
            action = np.clip((self._asked - self._targets) / span, -1.0, 1.0)
            self._targets = advance_targets(self._targets, action, self.limits)
            return action.astype(np.float32)

    def take_enter(self) -> bool:
        """Whether Enter was pressed since the last call."""
        with self._lock:
            pressed, self.enter_pressed = self.enter_pressed, False
            return pressed


def help_lines() -> list[tuple[str, str]]:
    """(key, what it does) for the on-screen and printed help."""
    return [(keys, doc) for _, (_, keys, doc) in BINDINGS.items()]


class Viewer(Protocol):
    """What :func:`run_session` needs of a viewer (``mujoco.viewer.Handle`` has it)."""

    def is_running(self) -> bool: ...
    def sync(self) -> None: ...
    def lock(self) -> Any: ...
    def set_texts(self, texts: Any) -> None: ...


@dataclass
class SessionOptions:
    """How a manual session runs."""

    out_dir: Path = Path("out/manual")
    """where each finished episode's record goes."""
    seed: int = 0
    """seed of the first episode (the next ones count up)."""
    episodes: int = 0
    """stop after this many finished episodes; 0: until the window is closed."""
    speed: float = 1.0
    """simulated seconds per wall second (0.5: half speed, easier to drive)."""
    display_hz: float = 24.0
    """how often the viewer is refreshed, per simulated second."""


def run_session(env: Any, keys: TeleopKeys, viewer: Viewer, options: SessionOptions,
                sleep: Callable[[float], None] = time.sleep, clock: Callable[[], float] = time.perf_counter,
                echo: Callable[[str], None] = print) -> list[Path]:
    """Run manual episodes until the viewer closes (or ``options.episodes`` are done).

    Args:
        env: an autoscoop environment wrapped in ``autoscoop.evaluation.recorder.EpisodeRecorder``.
        keys: the key map the viewer's key callback feeds.
        viewer: the window (``mujoco.viewer.launch_passive(...)``).
        options: where to save, seeds, pace.
        sleep, clock, echo: injectable for tests.

    Returns:
        The records saved.
    """
    scoop = env.unwrapped
    sim = scoop.sim
    interval = max(1, int(round(1.0 / (options.display_hz * float(sim.model.opt.timestep)))))
    pacer = _Pacer(sim, viewer, interval, scoop.config.substeps, options.speed, sleep, clock)
    saved: list[Path] = []
    seed = options.seed
    sim.add_substep_observer(pacer.after_physics_step)  # this sim only, detached below
    manual = _KeyboardPolicy(keys, viewer, pacer, scoop.config.robot.start_lift_rad,
                             scoop.config.robot.start_tilt_rad)
    try:
        while viewer.is_running() and (options.episodes <= 0 or len(saved) < options.episodes):
            end = _EpisodeEnd(keys, viewer)
            rollout(manual, env, seed, observers=(manual.after_step, _status_shower(viewer, keys, seed)),
                    transition_observers=(end.observe,), stop=end.asked)
            if not end.finished:  # the window closed mid-episode: nothing to save
                break
            info, truncated = end.info, end.truncated
            stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
            path = env.save(Path(options.out_dir) / f"manual_{stamp}_seed{seed:05d}.npz", source="teleop",
                            policy="manual", ended="success" if info.get("success") else
                            ("time limit" if truncated else "stopped by hand"))
            saved.append(path)
            o = env.outcome()
            result = f"success in {o.cycle_time_s:.2f} s" if o.success else "no success"
            echo(f"episode {len(saved)}: {o.mass_kg:.2f} kg ({o.particles} particles), {result}; saved {path}")
            seed += 1
            if options.episodes <= 0 or len(saved) < options.episodes:
                echo("press Enter in the window for the next episode, or close it to quit")
                while viewer.is_running() and not keys.take_enter():
                    viewer.sync()
                    sleep(0.05)
    finally:
        pacer.end_step()
        sim.remove_substep_observer(pacer.after_physics_step)
    return saved


class _KeyboardPolicy:
    """The person at the keyboard as a :class:`autoscoop.core.policy.Policy`: each action is what the
    keys held now say; each step's physics is paced for the viewer."""

    name = "manual"

    def __init__(self, keys: TeleopKeys, viewer: Viewer, pacer: _Pacer, start_lift_rad: float,
                 start_tilt_rad: float) -> None:
        self.keys, self.viewer, self.pacer = keys, viewer, pacer
        self.start_targets = np.array([0.0, start_lift_rad, start_tilt_rad])

    def reset(self) -> None:
        self.keys.reset(self.start_targets.copy())
        self.viewer.sync()
        self.pacer.restart()

    def act(self, observation: np.ndarray) -> np.ndarray:
        action = self.keys.next_action()
        self.pacer.begin_step()
        return action

    def after_step(self, step: int, obs: np.ndarray, action: np.ndarray, reward: float, info: dict) -> None:
        self.pacer.end_step()


class _EpisodeEnd:
    """Why a manual episode ended: the environment (success, time limit), Enter, or a closed window."""

    def __init__(self, keys: TeleopKeys, viewer: Viewer) -> None:
        self.keys, self.viewer = keys, viewer
        self.info: dict = {}
        self.truncated = self.finished = False

    def observe(self, step: int, obs: np.ndarray, action: np.ndarray, reward: float, next_obs: np.ndarray,
                terminated: bool, truncated: bool, info: dict) -> None:
        self.info, self.truncated = info, truncated
        self.finished = terminated or truncated

    def asked(self) -> bool:
        """Stop now? Enter ends the episode (kept); a closed window ends it unsaved."""
        if self.keys.take_enter():
            self.finished = True
        return self.finished or not self.viewer.is_running()


def _status_shower(viewer: Viewer, keys: TeleopKeys, seed: int) -> Callable[..., None]:
    def show(step: int, obs: np.ndarray, action: np.ndarray, reward: float, info: dict) -> None:
        _show_status(viewer, keys, info, seed)
    return show


class _Pacer:
    """Shows the physics in (scaled) real time: a substep observer of the sim.

    Each environment step's physics steps run in chunks of ``interval`` (the last one shorter) under
    the viewer's lock; after each chunk the window is refreshed and the pace kept. Once the window is
    closed, the step's remaining physics runs unpaced, so the episode stays consistent.
    """

    def __init__(self, sim: Any, viewer: Viewer, interval: int, substeps: int, speed: float,
                 sleep: Callable[[float], None], clock: Callable[[], float]) -> None:
        self.sim, self.viewer, self.interval, self.substeps, self.speed = sim, viewer, interval, substeps, speed
        self.sleep, self.clock = sleep, clock
        self.wall0, self.sim0 = clock(), 0.0
        self.left = self.in_chunk = 0
        self.paced = False
        self.lock = contextlib.ExitStack()

    def restart(self) -> None:
        """Keep the pace from now on (an episode starts)."""
        self.wall0, self.sim0 = self.clock(), self.sim.elapsed_s

    def begin_step(self) -> None:
        """An environment step of ``substeps`` physics steps starts."""
        self.left, self.in_chunk = self.substeps, 0
        self._start_chunk()

    def end_step(self) -> None:
        """The environment step is over (or failed)."""
        self.lock.close()
        self.paced = False

    def after_physics_step(self) -> None:
        self.left -= 1
        if not self.paced:
            return
        self.in_chunk += 1
        if self.in_chunk == self.interval or self.left <= 0:
            self.lock.close()
            self.viewer.sync()
            behind = (self.sim.elapsed_s - self.sim0) / self.speed - (self.clock() - self.wall0)
            if behind > 0:
                self.sleep(behind)
            self.in_chunk = 0
            self._start_chunk()

    def _start_chunk(self) -> None:
        self.paced = self.left > 0 and self.viewer.is_running()
        if self.paced:
            self.lock.enter_context(self.viewer.lock())


def _show_status(viewer: Viewer, keys: TeleopKeys, info: dict, seed: int) -> None:
    import mujoco  # noqa: PLC0415 - the overlay's font and position constants

    asked = keys.asked
    help_keys = "\n".join(k for k, _ in help_lines())
    help_docs = "\n".join(d for _, d in help_lines())
    labels = "time\nasked speed\nasked lift\nasked tilt\nin bucket\nphase"
    values = (f"{info.get('elapsed_s', 0.0):.2f} s (seed {seed})\n{asked[0]:+.3f} m/s\n{asked[1]:+.2f} rad\n"
              f"{asked[2]:+.2f} rad\n{info.get('particles_in_bucket', 0)} particles, "
              f"{info.get('mass_in_bucket_kg', 0.0):.1f} kg\n"
              f"{'penetrating' if info.get('penetrating') else '-'}")
    viewer.set_texts([
        (mujoco.mjtFontScale.mjFONTSCALE_150, mujoco.mjtGridPos.mjGRID_TOPLEFT, help_keys, help_docs),
        (mujoco.mjtFontScale.mjFONTSCALE_150, mujoco.mjtGridPos.mjGRID_BOTTOMLEFT, labels, values),
    ])
