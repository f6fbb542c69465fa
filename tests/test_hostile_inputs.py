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
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from autoscoop.cli import main
from autoscoop.core import safe_files

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
CASES += [_train_init_case(algo) for algo in ("ddpg", "td3", "sac", "ppo")]


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
    "ros-robot-yaml": lambda path, tmp: ["ros", "controller", "--check", "--policy", "heuristic", "--config", path],
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
