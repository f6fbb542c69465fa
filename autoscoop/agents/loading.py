"""Turn a ``--policy`` argument into a controller."""

from __future__ import annotations

from pathlib import Path

from autoscoop.agents.heuristic import HeuristicScooper, machine_params
from autoscoop.core import kinematics
from autoscoop.core.config import ScoopConfig
from autoscoop.core.machine import Machine
from autoscoop.core.policy import Policy
from autoscoop.core.safe_files import UnsafeInputError, quote, read_json
from autoscoop.core.state import CommandLimits

DEFAULT_POLICY = "default"
"""Name of the machine's shipped policy (the Komodo's: ``autoscoop/policies/default.safetensors``; another
machine's: the file its ``machine.yaml`` names as ``default_policy``)."""


class PolicyError(ValueError):
    """A policy argument that cannot be loaded; the message says why and what is accepted."""


def heuristic_for(config: ScoopConfig) -> HeuristicScooper:
    """The scripted baseline, aimed at the config's terminal point, with its control period and speed limit."""
    return HeuristicScooper(machine_params(
        terminal_dx_m=config.reward.terminal_dx_m, terminal_z_m=config.reward.terminal_z_m,
        control_period_s=config.env.control_period_s,
        limits=CommandLimits.for_robot(config.robot)))


def default_policy_path(machine: Machine | None = None) -> Path:
    """The shipped policy's weights file of ``machine`` (default: the machine this process runs).

    Raises:
        PolicyError: the machine ships no trained controller.
    """
    machine = machine or kinematics.MACHINE
    path = machine.default_policy_path()
    if path is None:
        raise PolicyError(f"machine {machine.name} ships no trained controller (its machine.yaml names no "
                          f"default_policy): train one with `autoscoop train --machine {machine.name}` "
                          "and pass its run directory as --policy, or use --policy heuristic")
    return path


def load_policy(spec: str, config: ScoopConfig, trust: bool = False) -> Policy:
    """A controller from a ``--policy`` argument.

    Args:
        spec: ``heuristic`` (scripted baseline), ``default`` (the shipped policy), a ``.safetensors``
            actor file (safe), a run directory (its safe actor file; its ``policy.zip`` only where it has no
            safe one, and only with ``trust``), an ``.onnx`` file, or an SB3 ``.zip`` (only with ``trust``).
        config: the scene it will run in.
        trust: allow an SB3 zip, which unpickles (runs code) when loaded.

    Raises:
        PolicyError: if ``spec`` names nothing loadable, or a zip without ``trust``.
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
            raise PolicyError(f"the shipped policy is missing from this installation ({path})")
        return ActorPolicy(path, name=DEFAULT_POLICY)
    path = Path(spec)
    if path.is_dir():
        path = _policy_in_run_dir(path)
    if not path.exists():
        raise PolicyError(f"policy {spec!r} not found; use heuristic, default, a .safetensors/.onnx file, "
                          "a run directory, or an SB3 .zip (with --trust)")
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
    except ValueError as error:  # the ONNX runner's checks
        raise PolicyError(str(error)) from None
    raise PolicyError(f"policy file {path} has an unknown type; use .safetensors, .onnx or .zip")


def _policy_in_run_dir(run_dir: Path) -> Path:
    """A run directory's policy: its safe actor file, else its SB3 zip (loaded only with ``--trust``)."""
    for name in ("policy.safetensors", "policy.zip"):
        if (run_dir / name).is_file():
            return run_dir / name
    raise PolicyError(f"policy {run_dir}: a folder without policy.safetensors or policy.zip; give a training run "
                      "directory or a policy file")


def refuse_untrusted_zip(path: Path, trust: bool, option: str = "--policy") -> None:
    """Refuse an SB3 zip unless the user vouched for it with ``--trust``: loading one runs pickle.

    Nothing inside a folder vouches for a file in it (whoever can write the zip can write ``run.json``).

    Raises:
        PolicyError: ``trust`` is false.
    """
    if not trust:
        raise PolicyError(f"{option} {path}: a Stable-Baselines3 zip runs pickle when loaded, so it is loaded only "
                          "with --trust. Load the run's policy.safetensors instead (a run directory gives it when "
                          "it has one), or pass --trust if you trust where the zip came from.")


class SB3Policy:
    """A :class:`Policy` around a Stable-Baselines3 model (deterministic actions); with ``target``, DDPG's or
    TD3's target actor (the Polyak average of the actor's weights) acts instead of the actor."""

    def __init__(self, model: object, name: str, target: bool = False) -> None:
        self.model, self.name, self.target = model, name, target

    def reset(self) -> None:
        """SB3 policies here are stateless."""

    def act(self, observation):
        if not self.target:
            action, _ = self.model.predict(observation, deterministic=True)
            return action
        import torch  # noqa: PLC0415 - torch only where a model is

        policy = self.model.policy
        tensor, _ = policy.obs_to_tensor(observation)
        with torch.no_grad():  # as SB3's predict does for the actor: squashed to [-1, 1], then to the action space
            action = policy.actor_target(tensor).cpu().numpy().reshape(policy.action_space.shape)
        return policy.unscale_action(action) if policy.squash_output else action


def _load_sb3_zip(path: Path, trust: bool) -> Policy:
    refuse_untrusted_zip(path, trust)
    from autoscoop.agents.algorithms import ALGORITHMS  # noqa: PLC0415 - torch

    tried = []
    for name in sorted(ALGORITHMS, key=lambda algo: algo != _recorded_algo(path)):  # its run's algorithm first
        try:
            return SB3Policy(ALGORITHMS[name].load(path, device="cpu"), name=f"{name}:{path.name}")
        except Exception as error:  # a trusted zip of another algorithm, or broken, fails anywhere in SB3 or pickle
            tried.append(f"{name}: {quote(str(error), 80)}")
    raise PolicyError(f"{path}: not a Stable-Baselines3 model of any of {sorted(ALGORITHMS)} ({'; '.join(tried)})")


def _recorded_algo(zip_path: Path) -> str | None:
    """The algorithm the ``run.json`` beside a zip names, if any (a hint for which class to load it with)."""
    try:
        info = read_json(zip_path.parent / "run.json", "run file")
    except UnsafeInputError:
        return None
    return info.get("algo") if isinstance(info, dict) else None
