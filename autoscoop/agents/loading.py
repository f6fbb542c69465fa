"""Turn a ``--policy`` argument into a controller."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

from autoscoop.agents.heuristic import HeuristicParams, HeuristicScooper
from autoscoop.core.config import ScoopConfig
from autoscoop.core.policy import Policy
from autoscoop.core.state import CommandLimits

DEFAULT_POLICY = "default"
"""Name of the policy shipped inside the package (``autoscoop/policies/default.safetensors``)."""


class PolicyError(ValueError):
    """A policy argument that cannot be loaded; the message says why and what is accepted."""


def heuristic_for(config: ScoopConfig) -> HeuristicScooper:
    """The scripted baseline, aimed at the config's terminal point, with its control period and speed limit."""
    return HeuristicScooper(HeuristicParams(
        terminal_dx_m=config.reward.terminal_dx_m, terminal_z_m=config.reward.terminal_z_m,
        control_period_s=config.env.control_period_s,
        limits=CommandLimits.for_robot(config.robot)))


def default_policy_path() -> Path:
    """The shipped policy's weights file."""
    return Path(str(resources.files("autoscoop") / "policies" / "default.safetensors"))


def load_policy(spec: str, config: ScoopConfig, trust: bool = False) -> Policy:
    """A controller from a ``--policy`` argument.

    Args:
        spec: ``heuristic`` (scripted baseline), ``default`` (the shipped policy), a ``.safetensors``
            actor file (safe), a run directory (its safe actor file), an ``.onnx`` file, or an SB3 ``.zip``.
        config: the scene it will run in.
        trust: allow an SB3 zip (which unpickles) that no autoscoop run directory vouches for.

    Raises:
        PolicyError: if ``spec`` names nothing loadable, or an untrusted zip without ``trust``.
    """
    if spec == "heuristic":
        return heuristic_for(config)
    if spec.endswith(".onnx") and Path(spec).is_file():  # before any torch import: the robot may lack torch
        from autoscoop.agents.onnx_policy import OnnxPolicy  # noqa: PLC0415

        return OnnxPolicy(spec)
    from autoscoop.agents.policy_files import ActorPolicy, PolicyFileError  # noqa: PLC0415 - torch

    if spec == DEFAULT_POLICY:
        path = default_policy_path()
        if not path.is_file():
            raise PolicyError("the shipped policy is missing from this installation (autoscoop/policies/default.*)")
        return ActorPolicy(path, name=DEFAULT_POLICY)
    path = Path(spec)
    if path.is_dir() and (path / "policy.safetensors").is_file():
        path = path / "policy.safetensors"
    elif path.is_dir() and (path / "policy.zip").is_file():  # PPO: no safe actor file; the run vouches for its zip
        path = path / "policy.zip"
    if not path.exists():
        raise PolicyError(f"policy {spec!r} not found; use heuristic, default, a .safetensors/.onnx file, "
                          "a run directory, or an SB3 .zip")
    try:
        if path.suffix in (".safetensors", ".json"):
            return ActorPolicy(path)
        if path.suffix == ".onnx":
            from autoscoop.agents.onnx_policy import OnnxPolicy  # noqa: PLC0415

            return OnnxPolicy(path)
        if path.suffix == ".zip":
            return _load_sb3_zip(path, trust)
    except PolicyFileError as error:
        raise PolicyError(str(error)) from error
    raise PolicyError(f"policy file {path} has an unknown type; use .safetensors, .onnx or .zip")


def zip_is_vouched_for(path: Path) -> bool:
    """Whether an autoscoop run directory records this zip's SHA-256 (``run.json`` beside it)."""
    from autoscoop.agents.policy_files import sha256_of  # noqa: PLC0415

    run_json = path.parent / "run.json"
    if not run_json.is_file():
        return False
    try:
        recorded = json.loads(run_json.read_text()).get("policy_zip_sha256")
    except json.JSONDecodeError:
        return False
    return recorded is not None and recorded == sha256_of(path)


class SB3Policy:
    """A :class:`Policy` around a Stable-Baselines3 model (deterministic actions)."""

    def __init__(self, model: object, name: str) -> None:
        self.model, self.name = model, name

    def reset(self) -> None:
        """SB3 policies here are stateless."""

    def act(self, observation):
        action, _ = self.model.predict(observation, deterministic=True)
        return action


def _load_sb3_zip(path: Path, trust: bool) -> Policy:
    if not trust and not zip_is_vouched_for(path):
        raise PolicyError(f"{path} is a Stable-Baselines3 zip, which runs pickle when loaded, and no autoscoop run "
                          "directory vouches for it (run.json with its SHA-256). Load its policy.safetensors "
                          "instead, or pass --trust if you trust where it came from.")
    from autoscoop.agents.algorithms import ALGORITHMS  # noqa: PLC0415 - torch

    algo = None
    run_json = path.parent / "run.json"
    if run_json.is_file():
        algo = json.loads(run_json.read_text()).get("algo")
    for name, cls in ALGORITHMS.items() if algo is None else [(algo, ALGORITHMS[algo])]:
        try:
            return SB3Policy(cls.load(path, device="cpu"), name=f"{name}:{path.name}")
        except (KeyError, ValueError, RuntimeError):
            continue
    raise PolicyError(f"{path}: not a model of any of {sorted(ALGORITHMS)}")
