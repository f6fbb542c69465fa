"""autoscoop: a wheel loader that learns to scoop.

Importing the package registers the Gymnasium environments (``autoscoop/Scoop-v1``, the paper's world;
``autoscoop/Scoop-v0``; ``autoscoop/ScoopRobot-v1``, the shipped policy's: see :mod:`autoscoop.envs`) and, on a
machine without a display, points MuJoCo at an off-screen OpenGL backend (``autoscoop.sim.glbackend``).
"""

from autoscoop.sim.glbackend import choose_gl_backend

choose_gl_backend()  # before anything imports mujoco, which reads MUJOCO_GL once

from autoscoop.core.version import __version__  # noqa: E402
from autoscoop.envs import register_envs  # noqa: E402
from autoscoop.training.recipes import register_recipe_worlds  # noqa: E402

__all__ = ["__version__"]

register_envs()
register_recipe_worlds()
