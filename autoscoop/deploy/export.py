"""Export a torch actor to ONNX, with its input and output scaling, and check it against torch.

The exported graph maps the raw 12-number state (``state``, float32, any batch size) to the action
in [-1, 1] (``action``): whatever the actor does to its input (the fixed state normalisation of
:class:`autoscoop.agents.networks.PaperActor`) and to its output (tanh) is inside the module, so it
is inside the file. :class:`autoscoop.agents.onnx_policy.OnnxPolicy` runs the file with onnxruntime
alone. The export uses torch's TorchScript-based exporter (``dynamo=False``), which needs nothing
beyond torch and onnx.
"""

from __future__ import annotations

import copy
import io
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from autoscoop.agents.onnx_policy import INPUT_NAME, ONNX_FORMAT, OUTPUT_NAME, OnnxPolicy
from autoscoop.core import kinematics
from autoscoop.core.machine import machine_record
from autoscoop.core.safe_files import write_bytes_atomically
from autoscoop.core.state import ACTION_NAMES, ACTION_SIZE, STATE_NAMES, STATE_SIZE, actor_input_size
from autoscoop.core.version import __version__

OPSET = 17
"""ONNX opset: 17 has LayerNormalization as one operator."""
PARITY_TOLERANCE = 5e-5
"""Largest allowed |onnx - torch| of any action component. Each runtime rounds in float32: for the
shipped ``default`` actor torch's own float32 actions are up to 1.2e-5 from the same network in
float64 (and onnxruntime's 1.2e-5), so two float32 runtimes can differ by about twice that; 5e-5 of an
action moves a target by at most 2e-5 rad or 1e-5 m/s (action x range), far below what the
servos resolve. ``check_parity`` reports both runtimes' distance from float64 beside it."""


def export_onnx(actor: Any, path: str | Path, metadata: dict[str, Any] | None = None) -> Path:
    """Write ``actor`` (a torch ``nn.Module``: raw state (n, 12) -> action (n, 3)) as an ONNX policy.

    Args:
        actor: the module; copied to the CPU in float32 and put in eval mode (the original is untouched).
        path: the ``.onnx`` file to write.
        metadata: extra string entries for the file's metadata (e.g. the source policy).

    Returns:
        The path written.
    """
    import onnx  # noqa: PLC0415
    import torch  # noqa: PLC0415

    path = Path(path)
    module = copy.deepcopy(actor).to("cpu").float().eval()
    history = int(getattr(actor, "history_steps", 1))
    size = actor_input_size(history)
    example = torch.zeros(1, size, dtype=torch.float32)
    buffer = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the TorchScript exporter's notice
        torch.onnx.export(module, (example,), buffer, input_names=[INPUT_NAME], output_names=[OUTPUT_NAME],
                          dynamic_axes={INPUT_NAME: {0: "batch"}, OUTPUT_NAME: {0: "batch"}},
                          opset_version=OPSET, dynamo=False)
    model = onnx.load_from_string(buffer.getvalue())
    entries = {"autoscoop_format": ONNX_FORMAT, "autoscoop_version": __version__,
               "state_names": ",".join(STATE_NAMES), "action_names": ",".join(ACTION_NAMES),
               "input": (f"{INPUT_NAME}: raw state (batch, {STATE_SIZE}) float32, autoscoop.core.state order"
                         if history == 1 else
                         f"{INPUT_NAME}: raw actor input (batch, {size}) float32: {history} states newest first, "
                         f"then {history} commands newest first (autoscoop.core.state.ActorInputHistory)"),
               **({"history_steps": str(history)} if history > 1 else {}),
               "output": f"{OUTPUT_NAME}: (batch, {len(ACTION_NAMES)}) in [-1, 1]",
               **machine_record(kinematics.MACHINE),
               **{str(k): str(v) for k, v in (metadata or {}).items()}}
    del model.metadata_props[:]
    for key, value in entries.items():
        model.metadata_props.add(key=key, value=value)
    onnx.checker.check_model(model)
    write_bytes_atomically(path, model.SerializeToString())  # a full disk leaves no partial .onnx
    return path


def random_states(n: int, seed: int = 0, rated_load_kg: float = kinematics.MACHINE.bucket.rated_load_kg) -> np.ndarray:
    """``n`` random states (n, 12) float32 over the robot's workspace, built by :func:`autoscoop.core.state.build_state`.

    Joint angles uniform over their ranges, mass 0-10 kg, 0-1.2 m to the pile, +-0.1 m/s, and the
    changes since the previous step within one step's reach (+-0.05 m/s, +-0.1 rad lift, +-0.25 rad tilt).
    """
    from autoscoop.core.state import Measurements, build_state  # noqa: PLC0415

    rng = np.random.default_rng(seed)
    lift = rng.uniform(*kinematics.LIFT_RANGE_RAD, n)
    tilt = rng.uniform(*kinematics.TILT_RANGE_RAD, n)
    mass = rng.uniform(0.0, 10.0, n)
    pile, speed = rng.uniform(0.0, 1.2, n), rng.uniform(-0.1, 0.1, n)
    change = np.column_stack([rng.uniform(-0.05, 0.05, n), rng.uniform(-0.1, 0.1, n), rng.uniform(-0.25, 0.25, n)])
    now = Measurements(mass_kg=mass, pile_distance_m=pile, speed_mps=speed, lift_rad=lift, tilt_rad=tilt)
    before = Measurements(mass_kg=mass, pile_distance_m=pile, speed_mps=speed - change[:, 0],
                          lift_rad=lift - change[:, 1], tilt_rad=tilt - change[:, 2])
    return build_state(now, before, rated_load_kg).T.copy()


def random_actor_inputs(n: int, history_steps: int = 1, seed: int = 0, rated_load_kg: float = 7.0) -> np.ndarray:
    """``n`` random raw inputs of an actor that reads ``history_steps`` states and commands (n, size) float32:
    :func:`random_states` for each state of the history, commands uniform in [-1, 1]; the states alone for 1."""
    if history_steps == 1:
        return random_states(n, seed, rated_load_kg)
    rng = np.random.default_rng(seed)
    states = [random_states(n, int(rng.integers(2**31)), rated_load_kg) for _ in range(history_steps)]
    actions = rng.uniform(-1.0, 1.0, (n, history_steps * ACTION_SIZE)).astype(np.float32)
    return np.concatenate([*states, actions], axis=1)


def check_parity(actor: Any, onnx_path: str | Path, states: np.ndarray, timing_steps: int = 2000) -> dict[str, Any]:
    """Compare the ONNX file with the torch actor on ``states``; time one step of each.

    Args:
        actor: the torch module that was exported.
        onnx_path: the exported file.
        states: (n, size) raw actor inputs to compare on (:func:`random_actor_inputs`).
        timing_steps: single-state calls timed for each runtime.

    Returns:
        ``max_abs_diff`` (over all states and action components), ``states``, ``passed``
        (``max_abs_diff <= PARITY_TOLERANCE``), ``torch_vs_float64`` and ``onnx_vs_float64`` (each
        runtime's largest distance from the same network run in float64), and per-step inference times in microseconds
        (median and 99th percentile) for onnxruntime (1 thread) and torch.
    """
    import torch  # noqa: PLC0415

    module = copy.deepcopy(actor).to("cpu").float().eval()
    policy = OnnxPolicy(onnx_path)
    states = np.asarray(states, dtype=np.float32)
    with torch.no_grad():
        expected = module(torch.as_tensor(states)).numpy()
        exact = copy.deepcopy(module).double()(torch.as_tensor(states, dtype=torch.float64)).numpy()
    got = policy.act_batch(states)
    diff = float(np.max(np.abs(got.astype(np.float64) - expected.astype(np.float64))))
    rounding = {"torch_vs_float64": float(np.max(np.abs(expected.astype(np.float64) - exact))),
                "onnx_vs_float64": float(np.max(np.abs(got.astype(np.float64) - exact)))}

    def timed(fn) -> dict[str, float]:
        times = np.empty(timing_steps)
        for k in range(timing_steps):
            state = states[k % len(states)]
            start = time.perf_counter()
            fn(state)
            times[k] = time.perf_counter() - start
        return {"median_us": float(np.median(times) * 1e6), "p99_us": float(np.percentile(times, 99) * 1e6)}

    def torch_step(state: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return module(torch.as_tensor(state).reshape(1, -1))[0].numpy()

    def onnx_step(state: np.ndarray) -> np.ndarray:
        return policy.act_batch(state.reshape(1, -1))[0]

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        for fn in (onnx_step, torch_step):  # warm up
            fn(states[0])
        onnx_time, torch_time = timed(onnx_step), timed(torch_step)
    finally:
        torch.set_num_threads(threads)
    return {"states": int(len(states)), "max_abs_diff": diff, **rounding, "tolerance": PARITY_TOLERANCE,
            "passed": bool(diff <= PARITY_TOLERANCE), "onnxruntime_step": onnx_time, "torch_step": torch_time}


def exportable_actor(policy: Any) -> Any:
    """The torch module behind a loaded policy (``policy.actor``), or a ``ValueError`` saying why not."""
    import torch  # noqa: PLC0415

    actor = getattr(policy, "actor", None)
    if not isinstance(actor, torch.nn.Module):
        why = ("it is already an ONNX file" if isinstance(policy, OnnxPolicy) else
               "a Stable-Baselines3 model; export its run's policy.safetensors" if hasattr(policy, "model") else
               "the heuristic is a script")
        shown = str(getattr(policy, "path", None) or getattr(policy, "name", policy))
        raise ValueError(f"policy {shown!r} has no neural network to export ({why}); export a "
                         "trained policy: default, a .safetensors file or a run directory")
    return actor
