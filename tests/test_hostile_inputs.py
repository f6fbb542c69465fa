"""Hostile files and full disks, as a table: every case runs one ``autoscoop`` command in-process and asserts
exit 2, a message naming the file or key, no traceback, every file already there unchanged, and no code run
from a file (a crafted pickle would create the marker file)."""

from __future__ import annotations

import errno
import hashlib
import json
import os
import pickle
import struct
import subprocess
import sys
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from filelock import FileLock

from autoscoop.cli import main
from autoscoop.commands import RECORDS_LOCK
from autoscoop.core import safe_files
from autoscoop.envs.records import STEP_FIELDS

MARKER = "pwned"
"""the file a crafted pickle creates, in the case's folder."""


@dataclass
class Probe:
    """One hostile command: its arguments, what the message must name, the files that must not change and
    the paths that must not appear."""

    argv: list[str]
    names: list[str]
    keep: list[Path] = field(default_factory=list)
    absent: list[Path] = field(default_factory=list)


@dataclass
class Case:
    """A named probe builder (given the case's empty folder)."""

    name: str
    build: Callable[[Path], Probe]

    def __str__(self) -> str:
        return self.name


class _Exploit:
    """A pickle payload: unpickling it creates the marker file."""

    def __init__(self, target: Path) -> None:
        self.target = target

    def __reduce__(self):
        return (Path.touch, (self.target,))


def exploit_zip(path: Path) -> Path:
    """An SB3-looking ``policy.zip`` whose pickles create the marker beside it when loaded."""
    payload = pickle.dumps(_Exploit(path.parent / MARKER))
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("data", json.dumps({"policy_class": {":serialized:": payload.hex()},
                                             "observation_space": {":serialized:": payload.hex()}}))
        archive.writestr("pytorch_variables.pth", payload)
        archive.writestr("policy.pth", payload)
    return path


def crafted_run(folder: Path, algo: str = "ddpg", with_actor: bool = False) -> Path:
    """A run directory whose ``run.json`` records its exploit zip's SHA-256 (it vouches for itself)."""
    folder.mkdir(parents=True, exist_ok=True)
    archive = exploit_zip(folder / "policy.zip")
    digest = hashlib.sha256(archive.read_bytes()).hexdigest()
    (folder / "run.json").write_text(json.dumps({"algo": algo, "status": "finished", "episodes": 1, "seed": 0,
                                                 "policy_zip_sha256": digest}))
    if with_actor:
        for suffix in (".safetensors", ".json"):
            (folder / f"policy{suffix}").write_bytes((SHIPPED / f"default{suffix}").read_bytes())
    return folder


SHIPPED = Path(__file__).resolve().parents[1] / "autoscoop" / "policies"


def run_cli(argv: list[str]) -> int:
    """``autoscoop ARGV`` in this process: its exit code (argparse's SystemExit included)."""
    try:
        return main([str(a) for a in argv])
    except SystemExit as exit_:
        return int(exit_.code or 0)


def snapshot(paths: list[Path]) -> dict[Path, bytes | None]:
    return {p: (p.read_bytes() if p.is_file() else None) for p in paths}


# ---------------------------------------------------------------------------------------------- trust
POLICY_COMMANDS: dict[str, Callable[[Path, Path], list[str]]] = {
    "eval": lambda policy, tmp: ["eval", "--policy", policy, "--episodes", "1"],
    "export": lambda policy, tmp: ["export", "--policy", policy, "--onnx", tmp / "out.onnx", "--check-states", "0"],
    "ros-check": lambda policy, tmp: ["ros", "controller", "--check", "--policy", policy],
    "stress": lambda policy, tmp: ["stress", "--policy", policy, "--episodes", "1", "--cases", "nominal",
                                   "--json", tmp / "stress.json", "--out", tmp / "stress"],
    "compare": lambda policy, tmp: ["compare", "--policies", "heuristic", policy, "--episodes", "1",
                                    "--angles", "32", "--out", tmp / "cmp"],
    "demo": lambda policy, tmp: ["demo", "--policy", policy, "--episodes", "1", "--no-video", "--out", tmp / "demo"],
}


def _trust_case(command: str, target: str) -> Case:
    def build(tmp: Path) -> Probe:
        run = crafted_run(tmp / "run")
        policy = run if target == "dir" else run / "policy.zip"
        return Probe(POLICY_COMMANDS[command](policy, tmp), ["--trust", str(run)], keep=[run / "policy.zip"],
                     absent=[tmp / "out.onnx", tmp / "cmp", tmp / "demo", tmp / "stress.json", tmp / "stress"])
    return Case(f"trust-{command}-{target}", build)


def _train_init_case(algo: str) -> Case:
    def build(tmp: Path) -> Probe:
        run = crafted_run(tmp / "run", algo=algo)
        return Probe(["train", "--algo", algo, "--recipe", "paper", "--init", run, "--episodes", "1", "--out", tmp / "new", "--no-progress"],
                     ["--init", "--trust"], keep=[run / "policy.zip", run / "run.json"], absent=[tmp / "new"])
    return Case(f"trust-train-init-{algo}", build)


CASES: list[Case] = [_trust_case(command, target) for command in POLICY_COMMANDS for target in ("dir", "zip")]
CASES += [_train_init_case(algo) for algo in ("ddpg", "td3", "sac", "tqc", "ppo")]


# ----------------------------------------------------------------------------------------- YAML files
def _alias_bomb(levels: int = 9) -> str:
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, levels)]
    return "\n".join(lines) + "\n"


HOSTILE_YAML: dict[str, tuple[str | bytes, str]] = {
    "alias-bomb": (_alias_bomb(), "aliases"),
    "alias-merge": ("base: &b {angle_deg: 20}\npile:\n  <<: *b\n", "aliases"),
    "duplicate-key": ("pile:\n  angle_deg: 20\n  angle_deg: 40\n", "appears more than once"),
    "duplicate-section": ("pile: {angle_deg: 20}\npile: {angle_deg: 40}\n", "appears more than once"),
    "deep-nesting": ("[" * 200 + "]" * 200, "nested deeper"),
    "python-tag": ("pile: !!python/object/apply:os.system ['touch pwned']\n", "not valid YAML"),
    "binary": (b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe", "not UTF-8"),
    "oversized": ("# " + "x" * (1 << 20) + "\n", "larger than"),
    "syntax": ("pile: [1, 2\n", "not valid YAML"),
    "huge-string": ("pile:\n  angle_deg: " + "9" * 20000 + "x\n", "pile.angle_deg"),
}
YAML_COMMANDS: dict[str, Callable[[Path, Path], list[str]]] = {
    "eval": lambda path, tmp: ["eval", "--policy", "heuristic", "--episodes", "1", "--config", path],
    "config": lambda path, tmp: ["config", "--config", path],
    "train": lambda path, tmp: ["train", "--config", path, "--episodes", "1", "--out", tmp / "new", "--no-progress"],
    "sweep-space": lambda path, tmp: ["sweep", "--space", path, "--trials", "1", "--episodes", "1", "--out", tmp / "new"],
    "ros-robot-yaml": lambda path, tmp: ["ros", "controller", "--check", "--policy", "heuristic", "--robot", path],
}


def _yaml_case(command: str, kind: str) -> Case:
    content, expected = HOSTILE_YAML[kind]

    def build(tmp: Path) -> Probe:
        path = tmp / "hostile.yaml"
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
        if kind == "huge-string" and command in ("sweep-space", "ros-robot-yaml"):
            names = [str(path)]  # another schema: the key differs, the file is named
        else:
            names = [str(path) if kind != "huge-string" else "", expected]
        return Probe(YAML_COMMANDS[command](path, tmp), names, keep=[path], absent=[tmp / "new", tmp / MARKER])
    return Case(f"yaml-{command}-{kind}", build)


CASES += [_yaml_case(command, kind) for command in YAML_COMMANDS for kind in HOSTILE_YAML]


# ---------------------------------------------------------------------------------------- policy files
def _actor_files(folder: Path, weights: bytes | None = None, **sidecar_changes) -> Path:
    """A copy of the shipped actor in ``folder`` (``weights`` replacing its bytes, the sidecar's hash made to match
    them, unless ``sha256`` is given), with ``sidecar_changes`` applied to its sidecar."""
    folder.mkdir(parents=True, exist_ok=True)
    data = weights if weights is not None else (SHIPPED / "default.safetensors").read_bytes()
    (folder / "policy.safetensors").write_bytes(data)
    sidecar = json.loads((SHIPPED / "default.json").read_text())
    sidecar.update(sha256=hashlib.sha256(data).hexdigest())
    sidecar.update(sidecar_changes)
    (folder / "policy.json").write_text(json.dumps(sidecar))
    return folder / "policy.safetensors"


def _shipped_weights_with_nan() -> bytes:
    from safetensors.numpy import load_file, save

    tensors = load_file(str(SHIPPED / "default.safetensors"))
    tensors["head.bias"] = np.full_like(tensors["head.bias"], np.nan)
    return save(tensors)


def _safetensors_claiming(shape: list[int]) -> bytes:
    """A safetensors file whose header declares one float32 tensor of ``shape`` but holds 16 bytes."""
    header = json.dumps({"head.weight": {"dtype": "F32", "shape": shape, "data_offsets": [0, 4 * int(np.prod(shape))]}})
    return struct.pack("<Q", len(header)) + header.encode() + bytes(16)


def _onnx_file(path: Path, dtype: int, input_shape: list, output_shape: list, formatted: bool = True) -> Path:
    """A tiny ONNX graph ``action = tanh(state @ W)`` with the given input element type and shapes."""
    import onnx
    from onnx import helper, numpy_helper

    weights = np.zeros((12, 3), dtype=onnx.helper.tensor_dtype_to_np_dtype(dtype))
    graph = helper.make_graph(
        [helper.make_node("MatMul", ["state", "W"], ["z"]), helper.make_node("Tanh", ["z"], ["action"])], "g",
        [helper.make_tensor_value_info("state", dtype, input_shape)],
        [helper.make_tensor_value_info("action", dtype, output_shape)],
        [numpy_helper.from_array(weights, "W")])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    if formatted:
        model.metadata_props.add(key="autoscoop_format", value="autoscoop-onnx-policy/1")
    onnx.save(model, str(path))
    return path


def _sidecar_text(folder: Path, text: str) -> Path:
    weights = _actor_files(folder)
    weights.with_suffix(".json").write_text(text)
    return weights


HOSTILE_POLICIES: dict[str, tuple[Callable[[Path], Path], str]] = {
    "huge-layers": (lambda d: _actor_files(d, layers=[2_000_000_000]), "'layers'"),
    "many-layers": (lambda d: _actor_files(d, layers=[8] * 1000), "'layers'"),
    "other-layers": (lambda d: _actor_files(d, layers=[100, 80, 61]), "do not fit"),
    "bool-layers": (lambda d: _actor_files(d, layers=[True, 80, 60]), "'layers'"),
    "truncated-weights": (lambda d: _actor_files(d, (SHIPPED / "default.safetensors").read_bytes()[:5000]),
                          "safetensors"),
    "garbage-weights": (lambda d: _actor_files(d, bytes(range(256)) * 8), "safetensors"),
    "empty-weights": (lambda d: _actor_files(d, b""), "safetensors"),
    "header-claims-huge": (lambda d: _actor_files(d, _safetensors_claiming([2_000_000_000, 12])), "safetensors"),
    "wrong-hash": (lambda d: _actor_files(d, sha256="0" * 64), "SHA-256"),
    "nan-weights": (lambda d: _actor_files(d, _shipped_weights_with_nan()), "NaN"),
    "huge-hash": (lambda d: _actor_files(d, sha256="f" * 50_000), "SHA-256"),
    "other-format": (lambda d: _actor_files(d, format="x" * 5000), "format"),
    "bad-state-frame": (lambda d: _actor_files(d, state_frame="upside-down"), "state_frame"),
    "sidecar-not-json": (lambda d: _sidecar_text(d, "{not json"), "not valid JSON"),
    "sidecar-list": (lambda d: _sidecar_text(d, "[1, 2]"), "JSON object"),
    "sidecar-deep": (lambda d: _sidecar_text(d, "[" * 100_000 + "]" * 100_000), "policy sidecar"),
    "sidecar-oversized": (lambda d: _sidecar_text(d, json.dumps({"pad": "x" * 200_000})), "larger than"),
    "onnx-float64": (lambda d: _onnx_file(d / "p.onnx", 11, ["batch", 12], ["batch", 3]), "float32"),
    "onnx-rank1": (lambda d: _onnx_file(d / "p.onnx", 1, [12], [3]), "(batch, 12)"),
    "onnx-width": (lambda d: _onnx_file(d / "p.onnx", 1, ["batch", 13], ["batch", 3]), "ONNX policy"),
    "onnx-output-rank1": (lambda d: _onnx_file(d / "p.onnx", 1, ["batch", 12], [3]), "output"),
    "onnx-unformatted": (lambda d: _onnx_file(d / "p.onnx", 1, ["batch", 12], ["batch", 3], formatted=False),
                         "autoscoop_format"),
    "onnx-garbage": (lambda d: (d / "p.onnx").write_bytes(b"\x08\x07garbage" * 50) and d / "p.onnx", "ONNX policy"),
}


def _policy_case(command: str, kind: str) -> Case:
    make, expected = HOSTILE_POLICIES[kind]

    def build(tmp: Path) -> Probe:
        folder = tmp / "pol"
        folder.mkdir()
        policy = make(folder)
        if kind.startswith("onnx") and command == "export":
            return Probe(POLICY_COMMANDS[command](policy, tmp), [str(policy)], keep=[policy], absent=[tmp / "out.onnx"])
        return Probe(POLICY_COMMANDS[command](policy, tmp), [str(policy.with_suffix("")), expected],
                     keep=sorted(folder.iterdir()), absent=[tmp / "out.onnx"])
    return Case(f"policy-{command}-{kind}", build)


CASES += [_policy_case(command, kind) for command in ("eval", "export", "ros-check") for kind in HOSTILE_POLICIES]


# --------------------------------------------------------------------------------------------- records
STEPS = 4


def _fields(**changes) -> dict[str, np.ndarray]:
    widths = {"state": 12, "action": 3, "tip_world_m": 3}
    arrays = {name: np.zeros((STEPS, widths[name]) if name in widths else STEPS) for name in STEP_FIELDS}
    arrays["time_s"] = np.arange(1, STEPS + 1) * 0.25
    arrays.update(changes)
    return arrays


OUTCOME = {"seed": 0, "fill_factor": 0.5, "mass_kg": 3.5, "particles": 12, "success": True, "cycle_time_s": 5.0,
           "spilled": 0, "physics_error": False, "steps": STEPS, "episode_return": 3.0}


def _record(path: Path, meta: object = None, raw_meta: str | None = None, **changes) -> Path:
    meta = {"policy": "crafted", "seed": 0, "autoscoop_version": "0.1.0", "outcome": OUTCOME} if meta is None else meta
    np.savez(path, meta=np.array(raw_meta if raw_meta is not None else json.dumps(meta)), **_fields(**changes))
    return path


def _zip_bomb(path: Path) -> Path:
    """A record whose arrays claim gigabytes once decompressed (zeros compress to almost nothing)."""
    fields = _fields()
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, array in fields.items():
            with archive.open(f"{name}.npy", "w", force_zip64=True) as handle:
                np.lib.format.write_array(handle, array)
        with archive.open("meta.npy", "w", force_zip64=True) as handle:
            np.lib.format.write_array(handle, np.array(json.dumps({"policy": "x"})))
        with archive.open("pad.npy", "w", force_zip64=True) as handle:
            for _ in range(300):
                handle.write(bytes(1 << 20))
    return path


def _saved(path: Path, **arrays: np.ndarray) -> Path:
    np.savez(path, **arrays)
    return path


def _written(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


def _pickled(path: Path) -> Path:
    fields = _fields()
    fields["state"] = np.array([_Exploit(path.parent / MARKER)] * STEPS, dtype=object)
    np.savez(path, meta=np.array("{}"), **fields)
    return path


HOSTILE_RECORDS: dict[str, tuple[Callable[[Path], Path], str]] = {
    "future-version": (lambda p: _record(p, {"autoscoop_version": "99.0.0"}), "99.0.0"),
    "not-a-version": (lambda p: _record(p, {"autoscoop_version": "banana"}), "autoscoop_version"),
    "nan-state": (lambda p: _record(p, state=np.full((STEPS, 12), np.nan)), "state"),
    "inf-reward": (lambda p: _record(p, reward=np.array([0, np.inf, 0, 0])), "reward"),
    "nan-time": (lambda p: _record(p, time_s=np.array([0.25, np.nan, 0.75, 1.0])), "time_s"),
    "empty": (lambda p: _record(p, **{name: array[:0] for name, array in _fields().items()}), "empty"),
    "ragged": (lambda p: _record(p, action=np.zeros((STEPS + 3, 3))), "action"),
    "wrong-width": (lambda p: _record(p, state=np.zeros((STEPS, 5))), "state"),
    "scalar-field": (lambda p: _record(p, reward=np.float64(1.0)), "reward"),
    "text-field": (lambda p: _record(p, reward=np.array(["a", "b", "c", "d"])), "reward"),
    "meta-list": (lambda p: _record(p, meta=[1, 2]), "meta"),
    "meta-policy-number": (lambda p: _record(p, {"policy": 5, "outcome": OUTCOME}), "meta.policy"),
    "meta-pile-text": (lambda p: _record(p, {"pile": "steep", "outcome": OUTCOME}), "meta.pile"),
    "meta-pile-angle-text": (lambda p: _record(p, {"pile": {"angle_deg": "steep"}, "outcome": OUTCOME}),
                             "meta.pile.angle_deg"),
    "meta-config-list": (lambda p: _record(p, {"config": [1], "outcome": OUTCOME}), "meta.config"),
    "meta-start-short": (lambda p: _record(p, {"start": {"tip_world_m": [1]}, "outcome": OUTCOME}),
                         "meta.start.tip_world_m"),
    "meta-terminal-text": (lambda p: _record(p, {"terminal_point_m": "abc", "outcome": OUTCOME}),
                           "meta.terminal_point_m"),
    "meta-outcome-number": (lambda p: _record(p, {"outcome": 3}), "meta.outcome"),
    "meta-outcome-partial": (lambda p: _record(p, {"outcome": {"fill_factor": 0.5}}), "meta.outcome"),
    "meta-not-json": (lambda p: _record(p, raw_meta="{policy: "), "record"),
    "meta-deep": (lambda p: _record(p, raw_meta="[" * 100_000 + "]" * 100_000), "record"),
    "missing-field": (lambda p: _saved(p, meta=np.array("{}"), time_s=np.zeros(2)), "missing"),
    "pickled-array": (_pickled, "record"),
    "zip-bomb": (_zip_bomb, "decompress"),
    "garbage": (lambda p: _written(p, b"PK\x03\x04 garbage" * 100), "record"),
    "truncated": (lambda p: _written(p, _record(p).read_bytes()[:300]), "record"),
}
RECORD_COMMANDS: dict[str, Callable[[Path, Path], list[str]]] = {
    "report": lambda record, tmp: ["report", record, "--out", tmp / "new"],
    "report-folder": lambda record, tmp: ["report", record.parent, "--out", tmp / "new"],
    "payload-calibrate": lambda record, tmp: ["payload", "calibrate", record, "--write", tmp / "new" / "cal.yaml"],
}


def _record_case(command: str, kind: str) -> Case:
    make, expected = HOSTILE_RECORDS[kind] if kind in HOSTILE_RECORDS else REPORT_ONLY_RECORDS[kind]

    def build(tmp: Path) -> Probe:
        folder = tmp / "records"
        folder.mkdir()
        record = make(folder / "episode_00000.npz")
        return Probe(RECORD_COMMANDS[command](record, tmp), [str(record), expected], keep=[record],
                     absent=[tmp / "new"])
    return Case(f"record-{command}-{kind}", build)


REPORT_ONLY_RECORDS = {
    "no-outcome": (lambda p: _record(p, {"policy": "x"}), "meta.outcome"),
}
CASES += [_record_case(command, kind) for command in RECORD_COMMANDS for kind in HOSTILE_RECORDS]
CASES += [_record_case(command, kind) for command in ("report", "report-folder") for kind in REPORT_ONLY_RECORDS]


# ----------------------------------------------------------------------------------- training settings
HOSTILE_HYPER = {
    "batch-zero": ("hyperparams.batch_size=0", "hyperparams.batch_size"),
    "batch-negative": ("hyperparams.batch_size=-5", "hyperparams.batch_size"),
    "gamma-two": ("hyperparams.gamma=2.0", "hyperparams.gamma"),
    "gamma-zero": ("hyperparams.gamma=0.0", "hyperparams.gamma"),
    "lr-nan": ("hyperparams.learning_rate=nan", "hyperparams.learning_rate"),
    "lr-inf": ("hyperparams.learning_rate=inf", "hyperparams.learning_rate"),
    "lr-negative": ("hyperparams.learning_rate=-0.001", "hyperparams.learning_rate"),
    "tau-zero": ("hyperparams.tau=0.0", "hyperparams.tau"),
    "buffer-zero": ("hyperparams.buffer_size=0", "hyperparams.buffer_size"),
    "train-freq-zero": ("hyperparams.train_freq=0", "hyperparams.train_freq"),
    "gradient-steps-zero": ("hyperparams.gradient_steps=0", "hyperparams.gradient_steps"),
    "learning-starts-negative": ("hyperparams.learning_starts=-1", "hyperparams.learning_starts"),
    "sigma-negative": ("noise.sigma_start=-0.1", "noise.sigma_start"),
    "theta-zero": ("noise.theta=0.0", "noise.theta"),
    "unknown-key": ("hyperparams.lr=1", "hyperparams.lr"),
}


def _hyper_case(kind: str) -> Case:
    setting, key = HOSTILE_HYPER[kind]

    def build(tmp: Path) -> Probe:
        return Probe(["train", "--recipe", "paper", "--episodes", "1", "--hyper", setting, "--out", tmp / "new",
                      "--no-progress"], [key], absent=[tmp / "new"])
    return Case(f"hyper-{kind}", build)


CASES += [_hyper_case(kind) for kind in HOSTILE_HYPER]
CASES += [Case("hyper-n-envs-huge", lambda tmp: Probe(["train", "--recipe", "paper", "--episodes", "1", "--n-envs",
                                                        "100000", "--out", tmp / "new", "--no-progress"],
                                                       ["--n-envs"], absent=[tmp / "new"]))]


# ------------------------------------------------------------------------------------------ run folders
def _run_folder(tmp: Path, run_json: str | None = None, **files: str) -> Path:
    run = tmp / "run"
    run.mkdir()
    if run_json is not None:
        (run / "run.json").write_text(run_json)
    for name, text in files.items():
        (run / name.replace("_yaml", ".yaml")).write_text(text)
    return run


HOSTILE_RUNS: dict[str, tuple[dict, str]] = {
    "run-json-garbage": ({"run_json": "{not json"}, "not valid JSON"),
    "run-json-list": ({"run_json": "[1, 2]"}, "JSON object"),
    "run-json-huge": ({"run_json": json.dumps({"pad": "x" * 2_000_000})}, "larger than"),
    "run-json-deep": ({"run_json": "[" * 100_000 + "]" * 100_000}, "run file"),
    "run-json-binary": ({"run_json": "\udcff"}, "run"),
    "hyperparams-alias-bomb": ({"run_json": json.dumps({"algo": "ddpg", "status": "running", "episodes": 2,
                                                        "seed": 0, "n_envs": 1, "checkpoint_every": 1}),
                                "hyperparams_yaml": _alias_bomb(), "config_yaml": "{}\n"}, "aliases"),
    "config-duplicate-key": ({"run_json": json.dumps({"algo": "ddpg", "status": "running", "episodes": 2, "seed": 0,
                                                      "n_envs": 1, "checkpoint_every": 1}),
                              "hyperparams_yaml": "algo: ddpg\n", "config_yaml": "pile: {}\npile: {}\n"},
                             "more than once"),
}


def _run_case(command: str, kind: str) -> Case:
    files, expected = HOSTILE_RUNS[kind]

    def build(tmp: Path) -> Probe:
        run_json = files.get("run_json")
        others = {k: v for k, v in files.items() if k != "run_json"}
        run = _run_folder(tmp, run_json.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
                          if run_json else run_json, **others)
        if kind == "run-json-binary":
            (run / "run.json").write_bytes(b"\xff\xfe\x00binary")
        argv = (["train", "--resume", run, "--no-progress"] if command == "resume" else
                ["train", "--recipe", "paper", "--init", run, "--episodes", "1", "--out", tmp / "new", "--no-progress"])
        return Probe(argv, [str(run), expected], keep=sorted(run.iterdir()), absent=[tmp / "new"])
    return Case(f"runfolder-{command}-{kind}", build)


CASES += [_run_case(command, kind) for command in ("resume", "init") for kind in HOSTILE_RUNS
          if command == "resume" or kind.startswith("run-json")]


# ---------------------------------------------------------------------------------------- calibrations
HOSTILE_CALIBRATIONS: dict[str, tuple[str | bytes, str]] = {
    "binary": (b"\x00\xff\xfe\x89", "not UTF-8"),
    "alias": ("a: &a [1]\nb: *a\n", "aliases"),
    "duplicate": ("format: autoscoop-payload-calibration/1\nformat: x\n", "more than once"),
    "not-calibration": ("just: text\n", "not an autoscoop payload calibration"),
    "oversized": ("# " + "x" * 100_000 + "\n", "larger than"),
}


def _calibration_case(kind: str) -> Case:
    content, expected = HOSTILE_CALIBRATIONS[kind]

    def build(tmp: Path) -> Probe:
        path = tmp / "cal.yaml"
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
        return Probe(["bench", "payload", "--calibration", path, "--episodes", "1", "--json", tmp / "new.json"],
                     [str(path), expected], keep=[path], absent=[tmp / "new.json"])
    return Case(f"calibration-bench-{kind}", build)


CASES += [_calibration_case(kind) for kind in HOSTILE_CALIBRATIONS]


# --------------------------------------------------------------------------------------- smaller cases
def _compare_over_earlier(tmp: Path) -> Probe:
    earlier = tmp / "cmp" / "records" / "heuristic" / "32deg" / "episode_00000.npz"
    earlier.parent.mkdir(parents=True)
    earlier.write_bytes(b"an earlier compare's record")
    return Probe(["compare", "--policies", "heuristic", "--episodes", "1", "--angles", "32", "--out", tmp / "cmp"],
                 ["--overwrite", str(tmp / "cmp")], keep=[earlier])


def _records_being_written(tmp: Path) -> Probe:
    folder = tmp / "rec"
    folder.mkdir()
    lock = FileLock(folder / RECORDS_LOCK)
    lock.acquire()  # another process's run, as far as this one can tell: released when the case's test ends
    _HELD.append(lock)
    return Probe(["eval", "--episodes", "1", "--records", folder], ["another autoscoop process", str(folder)],
                 absent=[folder / "episode_00000.npz"])


def _demo_records_being_written(tmp: Path) -> Probe:
    records = tmp / "demo" / "records"
    records.mkdir(parents=True)
    earlier = records / "episode_00000.npz"
    earlier.write_bytes(b"the other demo's record")
    lock = FileLock(records / RECORDS_LOCK)
    lock.acquire()  # another demo writing there, as far as this one can tell: released when the case's test ends
    _HELD.append(lock)
    return Probe(["demo", "--episodes", "1", "--no-video", "--out", tmp / "demo"],
                 ["another autoscoop process", str(records)], keep=[earlier], absent=[tmp / "demo" / "summary.json"])


def _inline_alias_bomb(levels: int = 8) -> str:
    items = ["&a0 [x, x, x, x, x, x, x, x, x]"]
    items += [f"&a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, levels)]
    return "[" + ", ".join(items) + "]"


_HELD: list = []
CASES += [
    Case("set-value-alias-bomb", lambda tmp: Probe(["eval", "--episodes", "1", "--set",
                                                     f"pile.angle_deg={_inline_alias_bomb()}"], ["pile.angle_deg"])),
    Case("hyper-value-alias-bomb", lambda tmp: Probe(["train", "--recipe", "paper", "--episodes", "1", "--hyper",
                                                       f"hyperparams.gamma={_inline_alias_bomb()}", "--out",
                                                       tmp / "new"], ["--hyper hyperparams.gamma", "aliases"],
                                                      absent=[tmp / "new"])),
    Case("hyper-value-not-yaml", lambda tmp: Probe(["train", "--recipe", "paper", "--episodes", "1", "--hyper",
                                                     "hyperparams.gamma=[1", "--out", tmp / "new"],
                                                    ["--hyper hyperparams.gamma", "not valid YAML"], absent=[tmp / "new"])),
]
CASES += [
    Case("cases-empty", lambda tmp: Probe(["stress", "--cases", "", "--episodes", "1", "--json", tmp / "s.json",
                                            "--out", tmp / "s"], ["--cases", "names no case"],
                                           absent=[tmp / "s.json", tmp / "s"])),
    Case("cases-commas", lambda tmp: Probe(["stress", "--cases", ",,", "--episodes", "1", "--json", tmp / "s.json",
                                             "--out", tmp / "s"], ["--cases"], absent=[tmp / "s.json", tmp / "s"])),
    Case("compare-over-earlier-records", _compare_over_earlier),
    Case("records-folder-locked", _records_being_written),
    Case("demo-records-folder-locked", _demo_records_being_written),
    Case("config-dev-zero", lambda tmp: Probe(["eval", "--episodes", "1", "--config", "/dev/zero"],
                                               ["/dev/zero", "larger than"])),
    Case("export-onnx-policy", lambda tmp: Probe(
        ["export", "--policy", _onnx_file(tmp / "p.onnx", 1, ["batch", 12], ["batch", 3]), "--onnx", tmp / "o.onnx"],
        [str(tmp / "p.onnx")], absent=[tmp / "o.onnx"])),
]


@pytest.mark.parametrize("case", CASES, ids=str)
def test_a_hostile_input_is_refused_cleanly(case: Case, tmp_path: Path, capsys, monkeypatch) -> None:
    folder = tmp_path / "case"
    folder.mkdir()
    probe = case.build(folder)
    before = snapshot(probe.keep)
    monkeypatch.chdir(folder)  # anything a command writes by default lands here, and the marker is looked for here too
    code = run_cli(probe.argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    for name in probe.names:
        assert name in err, f"{name!r} not in {err!r}"
    assert len(err) < 2000, f"a message of {len(err)} characters"
    assert snapshot(probe.keep) == before
    for path in probe.absent:
        assert not path.exists(), f"{path} was created"
    assert not list(tmp_path.rglob(MARKER)), "code ran from a file"


def test_the_suite_is_large_enough() -> None:
    assert len(CASES) >= 60



# ------------------------------------------------------------------------------------ environment API
class _EndsAtOnce(gym.Env):
    """An env whose every step terminates and pays 1."""

    observation_space = gym.spaces.Box(-1.0, 1.0, (1,))
    action_space = gym.spaces.Box(-1.0, 1.0, (1,))

    def reset(self, *, seed=None, options=None):
        return np.zeros(1, dtype=np.float32), {}

    def step(self, action):
        return np.zeros(1, dtype=np.float32), 1.0, True, False, {}


def test_step_after_termination_raises_until_reset() -> None:
    from autoscoop.envs.scoop import EndedEpisodeGuard

    env = EndedEpisodeGuard(_EndsAtOnce())
    env.reset()
    assert env.step(np.zeros(1))[2] is True
    with pytest.raises(gym.error.ResetNeeded, match="reset"):
        env.step(np.zeros(1))  # no second terminal bonus
    env.reset()
    assert env.step(np.zeros(1))[1] == 1.0


def test_step_after_the_time_limit_raises_until_reset() -> None:
    from autoscoop.envs.scoop import make_scoop_env

    env = make_scoop_env(**{"pile.variants": 1, "env.max_episode_s": 0.5})
    env.reset(seed=0)
    ended = [env.step(np.zeros(3))[3] for _ in range(2)]
    assert ended == [False, True]
    with pytest.raises(gym.error.ResetNeeded):
        env.step(np.zeros(3))
    env.reset(seed=0)
    env.step(np.zeros(3))
    env.close()


# ------------------------------------------------------------------------------------------ full disks
@pytest.fixture(params=["tmpfs", "injected"])
def full_disk(request, tmp_path, monkeypatch):
    """A folder on a 400 KiB tmpfs filled up to the last byte but for the files a case puts there first
    (skipped where mounting is not permitted: it needs root), or a folder whose atomic writes fail with ENOSPC
    (an injected fault)."""
    folder = tmp_path / "disk"
    folder.mkdir()
    mounted = False
    if request.param == "tmpfs":
        mounted = os.geteuid() == 0 and subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=400k", "tmpfs", str(folder)], capture_output=True).returncode == 0
        if not mounted:
            pytest.skip("cannot mount a tmpfs here")

    def fill() -> None:
        if not mounted:
            def no_space(path, flags):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            monkeypatch.setattr(safe_files, "_fsync", no_space)
            return
        with open(folder / ".filler", "wb", buffering=0) as handle:
            try:
                while True:
                    handle.write(bytes(4096))
            except OSError:
                pass

    yield folder, fill
    if mounted:
        subprocess.run(["umount", "-l", str(folder)], check=False)


def _records(tmp: Path) -> Path:
    folder = tmp / "records"
    if not folder.is_dir():
        assert run_cli(["eval", "--episodes", "1", "--records", folder, "--set", "pile.variants=1"]) == 0
    return folder


DISK_FULL: dict[str, Callable[[Path, Path], list[str]]] = {
    "eval-json": lambda disk, tmp: ["eval", "--episodes", "1", "--set", "pile.variants=1", "--json", disk / "old.json"],
    "eval-records": lambda disk, tmp: ["eval", "--episodes", "1", "--set", "pile.variants=1", "--records", disk / "rec"],
    "stress": lambda disk, tmp: ["stress", "--policy", "heuristic", "--episodes", "1", "--cases", "nominal",
                                 "--json", disk / "old.json", "--out", disk / "stress"],
    "export": lambda disk, tmp: ["export", "--onnx", disk / "old.onnx", "--check-states", "0"],
    "report": lambda disk, tmp: ["report", _records(tmp), "--out", disk / "report"],
    "compare": lambda disk, tmp: ["compare", "--policies", "heuristic", "--episodes", "1", "--angles", "32",
                                  "--set", "pile.variants=1", "--out", disk / "cmp"],
    "train": lambda disk, tmp: ["train", "--recipe", "paper", "--episodes", "1", "--out", disk / "run",
                                "--no-progress", "--set", "pile.variants=1"],
    "config-write": lambda disk, tmp: ["config", "--write", disk / "old.yaml"],
}


@pytest.mark.parametrize("command", DISK_FULL)
def test_a_full_disk_is_reported_and_loses_nothing(command, full_disk, tmp_path, capsys, monkeypatch) -> None:
    disk, fill = full_disk
    monkeypatch.chdir(tmp_path)
    argv = DISK_FULL[command](disk, tmp_path)
    capsys.readouterr()
    old = {disk / name: f"an earlier {name}".encode() for name in ("old.json", "old.onnx", "old.yaml")}
    for path, data in old.items():
        path.write_bytes(data)
    fill()
    code = run_cli(argv)
    out, err = capsys.readouterr()
    assert code == 2, err
    assert "Traceback" not in err and str(disk) in err
    assert "No space left on device" in err
    assert all(path.read_bytes() == data for path, data in old.items())
    leftovers = [p.name for p in disk.rglob("*") if p.is_file() and p.stat().st_size and p.name != ".filler"
                 and p not in old]
    assert not [name for name in leftovers if ".tmp" in name], leftovers
    assert not (disk / "run").exists()  # a run that failed before it began leaves no folder
    if command == "stress":
        assert "nominal" in out  # the measurements are shown although the files could not be written


# -------------------------------------------------------------------------------- small files stay small
SMALL_FILE_COMMANDS = {
    "config": ["config", "--config", "{file}"],
    "eval": ["eval", "--episodes", "1", "--config", "{file}"],
    "train": ["train", "--episodes", "1", "--config", "{file}", "--out", "{tmp}/run"],
    "resume": ["train", "--resume", "{tmp}", "--no-progress"],
    "sweep": ["sweep", "--space", "{file}", "--episodes", "1", "--trials", "1", "--out", "{tmp}/sweep"],
    "ros-robot-yaml": ["ros", "controller", "--check", "--policy", "heuristic", "--robot", "{file}"],
    "calibration": ["bench", "payload", "--calibration", "{file}", "--episodes", "1"],
}


MEASURED_RUN = """import os, subprocess, sys, time
start = time.perf_counter()
child = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
err = child.stderr.read()
_, status, usage = os.wait4(child.pid, 0)
child.returncode = os.waitstatus_to_exitcode(status)
print(child.returncode, usage.ru_maxrss, time.perf_counter() - start)
sys.stderr.write(err.decode())
"""
"""runs a command and prints its exit code, peak memory (KiB) and wall time (s): a process forked from this small
launcher, not from the test process (a child's peak memory counts what it had when forked, before exec)."""


@pytest.mark.parametrize("command", SMALL_FILE_COMMANDS)
def test_an_alias_bomb_of_under_1_kb_costs_little_memory_and_time(command, tmp_path) -> None:
    """The whole process, imports included: under 200 MB at its peak (about 110 MB measured) and a few
    seconds (under one second on an idle machine, 5.6 s measured with three training runs on the two
    cores; the bomb this guards against took 15 s and 0.9 GB, which the memory bound catches whatever the load)."""
    bomb = tmp_path / ("hyperparams.yaml" if command == "resume" else "bomb.yaml")
    bomb.write_text(_alias_bomb())
    assert bomb.stat().st_size <= 1024
    (tmp_path / "run.json").write_text(json.dumps({"algo": "ddpg", "status": "running", "episodes": 2}))
    argv = [arg.format(file=bomb, tmp=tmp_path) for arg in SMALL_FILE_COMMANDS[command]]
    done = subprocess.run([sys.executable, "-c", MEASURED_RUN, sys.executable, "-m", "autoscoop.cli", *argv],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120)
    code, peak_kib, wall_s = done.stdout.split()
    assert int(code) == 2 and "aliases" in done.stderr and "Traceback" not in done.stderr
    assert int(peak_kib) < 200 * 1024, f"{int(peak_kib) / 1024:.0f} MB"
    assert float(wall_s) < 12.0, f"{float(wall_s):.1f} s"


def test_a_frame_the_policy_overrides_is_warned_about(capsys) -> None:
    assert run_cli(["eval", "--policy", "default", "--episodes", "1", "--set", "pile.variants=1",
                    "--set", "sensor.level_with_imu=false"]) == 0
    err = capsys.readouterr().err
    assert "warning: sensor.level_with_imu = false is overridden" in err and "(level)" in err
    assert run_cli(["eval", "--policy", "default", "--episodes", "1", "--set", "pile.variants=1"]) == 0
    assert "warning" not in capsys.readouterr().err  # nothing asked for: nothing to warn about
