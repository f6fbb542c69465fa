"""autoscoop: a wheel loader that learns to scoop.

Importing the package registers the Gymnasium environment ``autoscoop/Scoop-v0``.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("autoscoop")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

from autoscoop.envs import register_envs

register_envs()
