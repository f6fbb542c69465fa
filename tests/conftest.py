"""Shared test set-up."""

# Import the package before any test module imports mujoco: on a machine without a display,
# ``import autoscoop`` points MUJOCO_GL at an off-screen backend, and mujoco reads it only once.
import autoscoop  # noqa: F401
