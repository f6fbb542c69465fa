"""Hostile files and full disks, as a table: every case runs one ``autoscoop`` command in-process and asserts
exit 2, a message naming the file or key, no traceback, every file already there unchanged, and no code run
from a file (a crafted pickle would create the marker file)."""

from __future__ import annotations

import hashlib
import json
import pickle
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from autoscoop.cli import main

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
    "compare": lambda policy, tmp: ["compare", "--policies", f"heuristic,{policy}", "--episodes", "1",
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

