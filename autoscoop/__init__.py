"""autoscoop: a wheel loader that learns to scoop.

Importing the package registers the Gymnasium environment ``autoscoop/Scoop-v0`` and, on a
machine without a display, points MuJoCo at an off-screen OpenGL backend (``autoscoop.glbackend``).
"""

from importlib.metadata import PackageNotFoundError, version

from autoscoop.glbackend import choose_gl_backend

choose_gl_backend()  # before anything imports mujoco, which reads MUJOCO_GL once

try:
    __version__ = version("autoscoop")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

from autoscoop.envs import register_envs

register_envs()
