"""Pick an off-screen OpenGL backend for MuJoCo when there is no display.

MuJoCo's Python bindings read ``MUJOCO_GL`` once, when ``mujoco`` is first imported, and default to
GLFW, which needs a display. ``import autoscoop`` calls :func:`choose_gl_backend` before anything
imports ``mujoco``, so videos render on a headless machine without the user setting anything.
A ``MUJOCO_GL`` the user has set is always kept.
"""

from __future__ import annotations

import ctypes.util
import os
import platform
from collections.abc import MutableMapping
from pathlib import Path

EGL_VENDOR_DIRS = ("/usr/share/glvnd/egl_vendor.d", "/etc/glvnd/egl_vendor.d")
"""Where GLVND looks for EGL drivers; ``libEGL.so`` without a driver listed here cannot render."""

INSTALL_HINT = ("no off-screen OpenGL found: install OSMesa (Debian/Ubuntu: apt-get install libosmesa6) "
                "or an EGL driver (libegl-mesa0), or set MUJOCO_GL to a backend that works here")


def egl_available() -> bool:
    """Whether an EGL library and at least one EGL driver (Mesa, NVIDIA) are installed."""
    if ctypes.util.find_library("EGL") is None:
        return False
    return any(Path(d).is_dir() and any(Path(d).glob("*.json")) for d in EGL_VENDOR_DIRS)


def osmesa_available() -> bool:
    """Whether the OSMesa software renderer is installed."""
    return ctypes.util.find_library("OSMesa") is not None


def has_display(environ: MutableMapping[str, str]) -> bool:
    """Whether a window can be opened (an X11 or Wayland display, or a desktop OS)."""
    if platform.system() != "Linux":
        return True
    return bool(environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY"))


def choose_gl_backend(environ: MutableMapping[str, str] | None = None) -> str | None:
    """Set ``MUJOCO_GL`` (and ``PYOPENGL_PLATFORM``) to ``egl`` or ``osmesa`` on a headless Linux.

    Args:
        environ: the environment to read and update; ``os.environ`` by default.

    Returns:
        The backend in effect afterwards (``None``: MuJoCo's default, GLFW, or nothing usable found).
    """
    environ = os.environ if environ is None else environ
    if environ.get("MUJOCO_GL"):
        return environ["MUJOCO_GL"]
    if has_display(environ):
        return None
    platform_gl = environ.get("PYOPENGL_PLATFORM", "").lower()
    if platform_gl in ("egl", "osmesa"):  # PyOpenGL is already told which one: agree with it
        environ["MUJOCO_GL"] = platform_gl
        return platform_gl
    for name, available in (("egl", egl_available), ("osmesa", osmesa_available)):
        if available():
            environ["MUJOCO_GL"] = name
            environ.setdefault("PYOPENGL_PLATFORM", name)
            return name
    return None
