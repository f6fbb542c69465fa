"""Run an exported actor (``autoscoop export --onnx``) with onnxruntime alone: no torch on the robot.

The file maps the raw 12-number state (float32, ``state``) to the 3-number action in [-1, 1]
(``action``); its input and output scaling are inside the graph. An actor that reads a short history
(metadata ``history_steps`` k > 1) maps k states and k commands instead, and :class:`OnnxPolicy` builds
that input from the states it is given with the same :class:`~autoscoop.core.state.ActorInputHistory`
as evaluation and training. :class:`OnnxPolicy` offers the
:class:`~autoscoop.core.policy.Policy` interface, so evaluation, the demo and the ROS controller run
it like any other controller.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from autoscoop.core import kinematics
from autoscoop.core.machine import refuse_other_machine
from autoscoop.core.safe_files import quote
from autoscoop.core.state import (
    ACTION_NAMES,
    ACTION_SIZE,
    STATE_NAMES,
    STATE_SIZE,
    ActorInputHistory,
    actor_input_size,
    checked_history_steps,
    recorded_state_frame,
)

ONNX_FORMAT = "autoscoop-onnx-policy/1"
"""Value of the ``autoscoop_format`` metadata entry of an exported policy."""
MAX_ONNX_BYTES = 64 << 20
"""cap of an ONNX policy file, bytes (the paper's actor is about 60 KB)."""
INPUT_NAME = "state"
OUTPUT_NAME = "action"


def _is_batch_of(args: list, name: str, width: int) -> bool:
    """Whether onnxruntime's inputs or outputs are exactly one float32 tensor ``name`` of shape (batch, width)."""
    return (len(args) == 1 and args[0].name == name and args[0].type == "tensor(float)"
            and len(args[0].shape) == 2 and args[0].shape[1] == width)


class OnnxPolicy:
    """A policy from an exported ONNX actor (``reset`` forgets the history of an actor that reads one).

    Args:
        path: the ``.onnx`` file.
        threads: onnxruntime's intra-op threads (1: the robot's computer runs other nodes too).

    Raises:
        ValueError: if the file is not an autoscoop policy (wrong inputs, outputs or metadata).
    """

    def __init__(self, path: str | Path, threads: int = 1) -> None:
        import onnxruntime as ort  # noqa: PLC0415 - only the robot's deploy extra needs it

        self.path = Path(path)
        if not self.path.is_file():
            raise ValueError(f"ONNX policy {self.path}: no such file")
        if self.path.stat().st_size > MAX_ONNX_BYTES:
            raise ValueError(f"ONNX policy {self.path}: larger than {MAX_ONNX_BYTES} bytes; not an actor autoscoop exports")
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
        options.log_severity_level = 3
        try:
            self.session = ort.InferenceSession(str(self.path), options, providers=["CPUExecutionProvider"])
        except Exception as error:  # onnxruntime raises its own exception types
            raise ValueError(f"ONNX policy {self.path}: cannot be loaded ({error})") from None
        self.metadata = dict(self.session.get_modelmeta().custom_metadata_map)
        if self.metadata.get("autoscoop_format") != ONNX_FORMAT:
            raise ValueError(f"ONNX policy {self.path}: not an autoscoop policy export (metadata autoscoop_format "
                             f"is {self.metadata.get('autoscoop_format')!r}, expected {ONNX_FORMAT!r}); "
                             "write it with `autoscoop export --onnx`")
        history = self.metadata.get("history_steps", "1")
        self.history = ActorInputHistory(checked_history_steps(int(history) if history.isdigit() else history,
                                                               f"ONNX policy {self.path}"))
        size = actor_input_size(self.history.history_steps)
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        if not _is_batch_of(inputs, INPUT_NAME, size):
            what = (f"(batch, {STATE_SIZE}) ({', '.join(STATE_NAMES)})" if size == STATE_SIZE
                    else f"(batch, {size}) ({self.history.history_steps} states and commands, newest first)")
            raise ValueError(f"ONNX policy {self.path}: expected one float32 input {INPUT_NAME!r} of shape {what}, "
                             f"got {quote([(i.name, i.type, i.shape) for i in inputs])}")
        if not _is_batch_of(outputs, OUTPUT_NAME, ACTION_SIZE):
            raise ValueError(f"ONNX policy {self.path}: expected one float32 output {OUTPUT_NAME!r} of shape "
                             f"(batch, {ACTION_SIZE}) ({', '.join(ACTION_NAMES)}), got "
                             f"{quote([(o.name, o.type, o.shape) for o in outputs])}")
        self.name = self.metadata.get("policy_name") or self.path.stem
        refuse_other_machine(self.metadata, kinematics.MACHINE, f"ONNX policy {self.path}")
        self.state_frame = recorded_state_frame(self.metadata, f"ONNX policy {self.path}")
        self._check_one_step()

    def _check_one_step(self) -> None:
        """Run the zero state once: a graph that fails or answers another shape fails now, not at the first step."""
        try:
            action = np.asarray(self.act(np.zeros(STATE_SIZE, dtype=np.float32)))
        except Exception as error:  # onnxruntime raises its own exception types
            raise ValueError(f"ONNX policy {self.path}: fails on a zero state ({quote(str(error))})") from None
        if action.shape != (ACTION_SIZE,) or not np.isfinite(action).all():
            raise ValueError(f"ONNX policy {self.path}: answers a zero state with {quote(action.tolist())}, expected "
                             f"{ACTION_SIZE} finite numbers")

    def reset(self) -> None:
        """Forget the episode's history (an actor of the state alone keeps none)."""
        self.history.reset()

    def act(self, observation: np.ndarray) -> np.ndarray:
        """The action (drive, lift, tilt) in [-1, 1] for one 12-number state (the actor's input built by
        :class:`~autoscoop.core.state.ActorInputHistory`)."""
        actor_input = self.history.observe(observation).reshape(1, -1)
        action = self.session.run(None, {INPUT_NAME: actor_input})[0][0]
        self.history.acted(action)
        return action

    def act_batch(self, inputs: np.ndarray) -> np.ndarray:
        """Actions (n, 3) for raw actor inputs (n, size): states (n, 12) for an actor of the state alone."""
        size = actor_input_size(self.history.history_steps)
        return self.session.run(None, {INPUT_NAME: np.asarray(inputs, dtype=np.float32).reshape(-1, size)})[0]
