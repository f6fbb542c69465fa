"""``autoscoop demo`` end to end on a short episode: table, video, GIF, figures; filming changes nothing."""

import os

import numpy as np
import pytest

from autoscoop.agents.loading import heuristic_for
from autoscoop.cli import main
from autoscoop.core.config import ScoopConfig
from autoscoop.envs.records import load_record
from autoscoop.evaluation.evaluate import evaluate
from autoscoop.evaluation.recorder import record_name
from autoscoop.sim.glbackend import choose_gl_backend, has_display

needs_gl = pytest.mark.skipif(not (os.environ.get("MUJOCO_GL") or has_display(os.environ)),
                              reason="no display and no off-screen OpenGL (install libosmesa6)")
SHORT = ["--set", "env.max_episode_s=1", "--set", "pile.variants=1"]


@needs_gl
def test_demo_runs_end_to_end_on_a_short_episode(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--policy", "heuristic", "--episodes", "2", "--out", str(out), *SHORT]) == 0
    printed = capsys.readouterr().out
    assert "fill factor" in printed and "demo took" in printed
    for name in ("scoop.mp4", "scoop.gif", "fig9_cycle.png", "fig11_bucket_torque.png", "report.md", "summary.json"):
        assert (out / name).is_file() and (out / name).stat().st_size > 1000, name
    assert len(list((out / "records").glob("*.npz"))) == 2
    assert "![the loader scooping](scoop.gif)" in (out / "report.md").read_text()

    import imageio.v2 as imageio

    reader = imageio.get_reader(out / "scoop.mp4")
    frames = [frame for frame in reader]
    assert reader.get_meta_data()["fps"] >= 8
    assert len(frames) >= 8 * 1.0, "at least 8 frames per simulated second"
    assert frames[0].shape == (432, 768, 3)
    assert np.abs(frames[-1].astype(int) - frames[0].astype(int)).mean() > 1, "the loader moved"
    assert len(imageio.mimread(out / "scoop.gif")) >= 4


@needs_gl
def test_filming_an_episode_does_not_change_it(tmp_path):
    from autoscoop.evaluation.render import render_episode

    config = ScoopConfig().with_overrides({"env.max_episode_s": 1.0, "pile.variants": 1})
    capture, filmed, _ = render_episode(heuristic_for(config), config, seed=1, fps=10, size=(192, 112))
    evaluate(heuristic_for(config), config, 1, seed=1, progress=False, records_dir=tmp_path)
    plain = load_record(tmp_path / record_name(1)).arrays()
    for name, values in filmed.arrays().items():
        np.testing.assert_array_equal(values, plain[name], err_msg=name)
    assert capture.fps >= 10 and len(capture.frames) == round(1.0 * capture.fps) + 1
    np.testing.assert_allclose(np.diff(capture.times_s), 1.0 / capture.fps, atol=1e-9)


def test_a_missing_shipped_policy_stops_the_demo_instead_of_showing_another(monkeypatch, tmp_path, capsys):
    from autoscoop.agents import loading
    from autoscoop.cli import main

    monkeypatch.setattr(loading, "default_policy_path", lambda: tmp_path / "default.safetensors")
    assert main(["demo", "--episodes", "1", "--no-video", "--out", str(tmp_path / "demo")]) == 2
    assert "shipped policy is missing" in capsys.readouterr().err
    assert not (tmp_path / "demo").exists()


def test_headless_machines_get_an_off_screen_backend(monkeypatch):
    import autoscoop.sim.glbackend as gl

    assert choose_gl_backend({"MUJOCO_GL": "glfw"}) == "glfw"
    assert choose_gl_backend({"DISPLAY": ":0"}) is None or os.name != "posix"
    monkeypatch.setattr(gl.platform, "system", lambda: "Linux")
    monkeypatch.setattr(gl, "egl_available", lambda: False)
    monkeypatch.setattr(gl, "osmesa_available", lambda: True)
    env = {}
    assert choose_gl_backend(env) == "osmesa" and env == {"MUJOCO_GL": "osmesa", "PYOPENGL_PLATFORM": "osmesa"}
    monkeypatch.setattr(gl, "egl_available", lambda: True)
    env = {}
    assert choose_gl_backend(env) == "egl" and env["PYOPENGL_PLATFORM"] == "egl"
    env = {"PYOPENGL_PLATFORM": "osmesa"}
    assert choose_gl_backend(env) == "osmesa"
    monkeypatch.setattr(gl, "egl_available", lambda: False)
    monkeypatch.setattr(gl, "osmesa_available", lambda: False)
    assert choose_gl_backend({}) is None
