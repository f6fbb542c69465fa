"""The installed package's version (``0.0.0+unknown`` in a source tree that is not installed), and the versions of
the libraries its figures depend on."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("autoscoop")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

MEASURED_WITH = ("mujoco", "numpy", "gymnasium", "torch", "stable-baselines3", "sb3-contrib")
"""Distributions whose version can change a measured figure: the simulator and its arrays move every rollout, the
learning libraries every trained policy."""


def dependency_versions() -> dict[str, str | None]:
    """Installed version of each distribution in :data:`MEASURED_WITH` (``None`` where it is not installed), read
    from the package metadata without importing it. Results files record it, so that a figure that moves with a
    library's version can be told from one that moved with the code."""
    versions: dict[str, str | None] = {}
    for name in MEASURED_WITH:
        try:
            versions[name] = version(name)
        except PackageNotFoundError:
            versions[name] = None
    return versions
