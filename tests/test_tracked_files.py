"""What the repository tracks stays evidence, not an archive: benchmarks/results is small, and policy weights
live only in autoscoop/policies/."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path, PurePosixPath

import pytest

ROOT = Path(__file__).resolve().parents[1]
RESULTS = "benchmarks/results"
RESULTS_LIMIT_BYTES = 3 * 1024 * 1024
RESULTS_LIMIT_FILES = 300
"""benchmarks/results keeps the summaries the pages cite; the rest is regenerable (docs/experiments/README.md)."""
FILE_LIMIT_BYTES = 256 * 1024
WEIGHT_SUFFIXES = (".safetensors", ".onnx", ".zip")
POLICIES = PurePosixPath("autoscoop/policies")


def tracked(*pathspecs: str) -> list[str]:
    """Paths that git tracks in this checkout (relative, POSIX), limited to ``pathspecs``."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    out = subprocess.run(["git", "ls-files", "-z", "--", *pathspecs], cwd=ROOT, capture_output=True, check=True).stdout
    return [name for name in out.decode().split("\0") if name]


def oversized(sizes: dict[str, int], total_limit: int, file_limit: int) -> list[str]:
    """Why a set of files is too big: each file over ``file_limit`` bytes, and the total over ``total_limit``."""
    found = [f"{name}: {size} bytes" for name, size in sorted(sizes.items()) if size > file_limit]
    total = sum(sizes.values())
    if total > total_limit:
        found.append(f"{total} bytes in all")
    return found


def weights_outside_policies(paths: list[str]) -> list[str]:
    """Weight files (by suffix) that are not under ``autoscoop/policies/``."""
    return [p for p in paths if p.endswith(WEIGHT_SUFFIXES) and POLICIES not in PurePosixPath(p).parents]


def test_the_checks_catch_what_they_look_for():
    assert oversized({"a.json": 10, "b.json": 300}, total_limit=100, file_limit=200) == ["b.json: 300 bytes",
                                                                                          "310 bytes in all"]
    assert oversized({"a.json": 10}, total_limit=100, file_limit=200) == []
    assert weights_outside_policies(["autoscoop/policies/default.safetensors", "benchmarks/results/x/best.zip",
                                     "runs/a/policy.onnx", "docs/x.md"]) == ["benchmarks/results/x/best.zip",
                                                                             "runs/a/policy.onnx"]


def test_benchmark_results_stay_small():
    sizes = {name: (ROOT / name).stat().st_size for name in tracked(RESULTS) if (ROOT / name).exists()}
    assert sizes, f"nothing tracked under {RESULTS}"
    assert oversized(sizes, RESULTS_LIMIT_BYTES, FILE_LIMIT_BYTES) == []
    assert len(sizes) <= RESULTS_LIMIT_FILES, f"{len(sizes)} files under {RESULTS} (at most {RESULTS_LIMIT_FILES})"


def test_policy_weights_live_only_in_the_package_policies():
    assert weights_outside_policies(tracked()) == []
