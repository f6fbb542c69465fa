"""``autoscoop sweep`` on Ray Tune: a bad space fails before any trial, naming the key; a two-trial sweep on
a real ``ray start --head`` cluster (loopback) writes run directories ``eval --policy`` loads, the table,
report, figure and best policy; a kill -9 of the driver and ``--resume`` on embedded Ray finish the rest
without training the finished trials again, and write the same. Each Ray test starts its own Ray (its own temporary folder and
home) and checks that no process of it is left."""

import csv
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import forked
import pytest

import autoscoop  # noqa: F401
from autoscoop.cli import main
from autoscoop.core.config import ConfigError
from autoscoop.training import sweep as sweep_module
from autoscoop.training.sweep_space import load_space, plan_trials, space_from_dict

SPACE = """
seeds: [0, 1]
config:
  pile.variants: 2
  reward.c_w: {choice: [30, 50]}
hyper:
  hyperparams.learning_starts: 50
  hyperparams.learning_rate: {loguniform: [3.0e-4, 3.0e-3]}
train: {eval_every: 3, eval_episodes: 1, checkpoint_every: 3}
"""
"""2 trials (one per seed), a few episodes each: learning starts after 50 steps, an evaluation every 3 episodes."""
KILL_SPACE = SPACE.replace("train: {eval_every: 3, eval_episodes: 1, checkpoint_every: 3}",
                           "train: {eval_every: 4, eval_episodes: 1, checkpoint_every: 4}")
SWEEP_TIMEOUT_S = 240


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


# --- the space file: checked before anything starts ------------------------------------------------------


@pytest.mark.parametrize("text, named", [
    ("config:\n  reward.cw: {choice: [30, 50]}\n", "reward.cw"),
    ("config:\n  reward.c_w: {normal: [30, 50]}\n", "config.reward.c_w"),
    ("config:\n  pile.angle_deg: {uniform: [25, 90]}\n", "pile.angle_deg"),
    ("config:\n  pile.variants: {uniform: [1, 3]}\n", "pile.variants"),
    ("hyper:\n  hyperparams.learning_rat: {loguniform: [1.0e-4, 1.0e-3]}\n", "hyperparams.learning_rat"),
    ("hyper:\n  hyperparams.learning_rate: {loguniform: [0, 1.0e-3]}\n", "hyper.hyperparams.learning_rate"),
    ("hyper:\n  hyperparams.batch_size: {choice: [64, big]}\n", "hyperparams.batch_size"),
    ("seeds: [0, -1]\n", "seeds"),
    ("train: {eval_every: 0}\n", "train.eval_every"),
    ("colour: red\n", "colour"),
])
def test_a_bad_space_file_fails_before_any_trial_naming_the_key(tmp_path, monkeypatch, capsys, text, named):
    def no_ray():
        raise AssertionError("Ray was reached with a bad space file")

    monkeypatch.setattr(sweep_module, "require_ray", no_ray)
    out = tmp_path / "sweep"
    code = main(["sweep", "--space", str(_write(tmp_path / "space.yaml", text)), "--trials", "2", "--episodes", "4",
                 "--out", str(out)])
    error = capsys.readouterr().err
    assert code == 2, error
    assert named in error and "space.yaml" in error, error
    assert not out.exists()


def test_trials_must_be_whole_passes_over_the_grid(tmp_path):
    space = load_space(_write(tmp_path / "space.yaml", SPACE))
    assert space.grid_size() == 2 and list(space.swept()) == ["reward.c_w", "hyperparams.learning_rate"]
    assert plan_trials(space, 4) == 2
    with pytest.raises(ValueError, match="--trials 3.*multiple of 2"):
        plan_trials(space, 3)
    fixed = space_from_dict({"seeds": [0, 1], "config": {"reward.c_w": {"grid": [30, 50]}}})
    with pytest.raises(ValueError, match="would repeat"):
        plan_trials(fixed, 8)
    assert space_from_dict(space.to_dict()) == space  # what --resume rebuilds from sweep_plan.json
    with pytest.raises(ConfigError, match="both config and hyper"):
        space_from_dict({"config": {"reward.c_w": 30}, "hyper": {"reward.c_w": 30}})


def test_without_ray_the_command_exits_2_naming_the_extra(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    monkeypatch.setitem(sys.modules, "ray.tune", None)
    code = main(["sweep", "--space", str(_write(tmp_path / "space.yaml", SPACE)), "--trials", "2", "--episodes", "4",
                 "--out", str(tmp_path / "sweep")])
    assert code == 2
    assert "pip install 'autoscoop[sweep]'" in capsys.readouterr().err


def test_resume_takes_the_sweeps_folder_and_the_old_spelling_is_refused_naming_it(tmp_path, capsys):
    folder = tmp_path / "sweep"
    assert main(["sweep", "--out", str(folder), "--resume"]) == 2
    assert f"--resume takes the sweep's folder: --resume {folder} (not --out {folder} --resume)" in \
        capsys.readouterr().err
    assert main(["sweep", "--resume", str(folder)]) == 2
    assert f"--resume {folder}: holds no sweep to resume" in capsys.readouterr().err
    assert main(["sweep", "--resume", str(folder), "--out", str(tmp_path / "other")]) == 2
    assert "a resumed sweep stays in its folder" in capsys.readouterr().err
    assert main(["sweep", "--space", str(_write(tmp_path / "space.yaml", SPACE)), "--trials", "2",
                 "--episodes", "4"]) == 2
    assert "--out must be given to start a sweep" in capsys.readouterr().err


def test_an_address_where_no_ray_head_listens_fails_at_once(tmp_path, capsys):
    pytest.importorskip("ray.tune", reason="Ray Tune is not installed (pip install 'autoscoop[sweep]')")
    with socket.socket() as closed:  # a port nothing listens on
        closed.bind(("127.0.0.1", 0))
        port = closed.getsockname()[1]
    out = tmp_path / "sweep"
    code = main(["sweep", "--space", str(_write(tmp_path / "space.yaml", SPACE)), "--trials", "2", "--episodes", "4",
                 "--out", str(out), "--address", f"127.0.0.1:{port}"])
    assert code == 2
    assert f"--address 127.0.0.1:{port}: no Ray head answers there" in capsys.readouterr().err
    assert not out.exists()


# --- real sweeps on Ray ---------------------------------------------------------------------------------------


@pytest.fixture
def ray_env():
    """Environment for a Ray of the test's own: a short temporary folder (Unix sockets live there) and home (Ray
    keeps its token in ~/.ray); after the test, every process carrying it is killed, and the test fails if the
    sweep left one behind."""
    pytest.importorskip("ray.tune", reason="Ray Tune is not installed (pip install 'autoscoop[sweep]')")
    root = Path(tempfile.mkdtemp(prefix="rs", dir="/tmp"))
    (root / "home").mkdir()
    env = {**os.environ, "RAY_TMPDIR": str(root), "HOME": str(root / "home"), "RAY_USAGE_STATS_ENABLED": "0"}
    env.pop("RAY_ADDRESS", None)
    yield env
    left = _ray_processes(root)
    _kill(left)
    shutil.rmtree(root, ignore_errors=True)
    assert not left, f"Ray processes left behind: {left}"


def _ray_processes(root: Path) -> list[int]:
    """PIDs of live processes whose environment holds ``RAY_TMPDIR=root`` (this test's Ray and its workers)."""
    marker = f"RAY_TMPDIR={root}".encode()
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if marker in (entry / "environ").read_bytes().split(b"\0"):
                found.append(int(entry.name))
        except OSError:  # gone, or not ours
            continue
    return found


def _kill(pids: list[int]) -> None:
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def _wait_for_no_ray(root: Path, within_s: float = 60.0) -> list[int]:
    """Wait for this test's Ray processes to end (a driver's Ray stops a moment after it); the ones still there."""
    deadline = time.time() + within_s
    while (left := _ray_processes(root)) and time.time() < deadline:
        time.sleep(0.25)
    return left


def _sweep(args: list[str], env: dict[str, str], timeout: float = SWEEP_TIMEOUT_S) -> subprocess.CompletedProcess:
    done = forked.run([sys.executable, "-m", "autoscoop.cli", "sweep", *args], env=env, capture_output=True,
                      text=True, timeout=timeout)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done


def _check_outputs(out: Path, trials: int, episodes: int) -> list[dict[str, str]]:
    """The table, report, figure and best policy are written and agree; each row's run directory is a finished
    ``autoscoop train`` run."""
    rows = list(csv.DictReader(open(out / "sweep.csv")))
    assert len(rows) == trials
    assert {"trial_id", "reward.c_w", "hyperparams.learning_rate", "seed", "score", "fill_factor", "success",
            "episodes_done", "wall_s", "status", "run_dir"} <= set(rows[0])
    assert sorted(int(r["seed"]) for r in rows) == [0, 1]
    for row in rows:
        assert row["status"] == "finished" and int(row["episodes_done"]) == episodes, row
        run_dir = Path(row["run_dir"])
        info = json.loads((run_dir / "run.json").read_text())
        assert info["status"] == "finished" and info["seed"] == int(row["seed"]) and info["episodes"] == episodes
        assert float(row["score"]) == pytest.approx(info["best_score"])
        for name in ("config.yaml", "hyperparams.yaml", "episodes.csv", "evaluations.csv", "policy.safetensors"):
            assert (run_dir / name).is_file(), name
    report = (out / "report.md").read_text()
    assert all(r["trial_id"] in report for r in rows) and "sweep.png" in report
    assert (out / "sweep.png").stat().st_size > 1000
    best = json.loads((out / "best.json").read_text())
    assert best["format"] == "autoscoop-actor/1" and best["sweep_trial"] in {r["trial_id"] for r in rows}
    return rows


def _eval_works(policy: Path) -> None:
    # a trial of a few episodes may scoop nothing yet: the policy loads and runs, which is what is asked
    assert main(["eval", "--policy", str(policy), "--episodes", "1", "--set", "pile.variants=2", "--allow-empty"]) == 0


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_two_trial_sweep_on_a_ray_cluster_at_an_address(tmp_path, ray_env):
    ray = str(Path(sys.executable).parent / "ray")
    port = _free_port()
    head = subprocess.run([ray, "start", "--head", f"--port={port}", "--node-ip-address=127.0.0.1", "--num-cpus=2",
                           "--include-dashboard=false", "--disable-usage-stats"],
                          env=ray_env, capture_output=True, text=True, timeout=120, start_new_session=True)
    root = Path(ray_env["RAY_TMPDIR"])
    try:
        assert head.returncode == 0, head.stdout[-2000:] + head.stderr[-2000:]
        out = tmp_path / "sweep"
        space = _write(tmp_path / "space.yaml", SPACE)
        done = _sweep(["--space", str(space), "--trials", "2", "--episodes", "6", "--out", str(out),
                       "--address", f"127.0.0.1:{port}"], ray_env)
        assert f"the Ray cluster at 127.0.0.1:{port}" in (out / "report.md").read_text()
        assert "[2/2 done]" in done.stdout
        _check_outputs(out, trials=2, episodes=6)
        assert _ray_processes(root), "the cluster should outlive the sweep's driver"
    finally:
        # not `ray stop`: it stops every Ray on the machine; this stops the processes of this cluster only
        for pid in _ray_processes(root):
            try:
                os.kill(pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
        _kill(_wait_for_no_ray(root, within_s=10.0))
    assert not _wait_for_no_ray(root, within_s=5.0)


def _status(run_dir: Path) -> str | None:
    try:
        return json.loads((run_dir / "run.json").read_text()).get("status")
    except (OSError, ValueError):
        return None


def _snapshot(run_dir: Path) -> dict[str, tuple[int, bytes]]:
    """Each file of a run directory (``tb`` aside): its modification time (ns) and its bytes."""
    return {str(p.relative_to(run_dir)): (p.stat().st_mtime_ns, p.read_bytes())
            for p in sorted(run_dir.rglob("*")) if p.is_file() and "tb" not in p.parts}


def test_kill_9_of_the_driver_then_resume_finishes_the_rest(tmp_path, ray_env, capsys):
    out = tmp_path / "sweep"
    space = _write(tmp_path / "space.yaml", KILL_SPACE)
    root = Path(ray_env["RAY_TMPDIR"])
    args = ["--space", str(space), "--trials", "2", "--episodes", "8", "--out", str(out), "--num-cpus", "1"]
    log = open(tmp_path / "driver.log", "w")
    driver = forked.Popen([sys.executable, "-m", "autoscoop.cli", "sweep", *args], env=ray_env, stdout=log,
                          stderr=subprocess.STDOUT, start_new_session=True)
    finished: list[Path] = []
    running: list[Path] = []
    deadline = time.time() + SWEEP_TIMEOUT_S
    try:  # one trial at a time: kill -9 once the first has finished and the second has checkpointed
        while time.time() < deadline and driver.poll() is None:
            runs = sorted((out / "runs").glob("*")) if (out / "runs").is_dir() else []
            finished = [d for d in runs if _status(d) == "finished"]
            running = [d for d in runs if _status(d) == "running" and (d / "checkpoint" / "state.json").is_file()]
            if finished and running:
                break
            time.sleep(0.05)
    finally:
        os.kill(driver.pid, signal.SIGKILL)
        driver.wait()
        log.close()
    assert driver.returncode == -signal.SIGKILL, (tmp_path / "driver.log").read_text()[-3000:]
    assert len(finished) == 1 and len(running) == 1, (tmp_path / "driver.log").read_text()[-3000:]
    # a killed driver's embedded Ray: its raylet takes the workers along, two agents stay (they keep its group)
    _kill(_wait_for_no_ray(root, within_s=5.0))
    assert not _wait_for_no_ray(root, within_s=5.0)
    kept = _snapshot(finished[0])

    assert main(["sweep", "--resume", str(out), "--trials", "4"]) == 2  # not the recorded settings
    assert "does not match" in capsys.readouterr().err

    # the resumed session runs on embedded Ray: its summary, ranking and best policy are what a whole sweep writes
    done = _sweep(["--resume", str(out), "--num-cpus", "1", "--space", str(space), "--json",
                   str(tmp_path / "sweep.json")], ray_env)
    assert "resuming the sweep" in done.stdout and "[2/2 done]" in done.stdout, done.stdout
    assert _snapshot(finished[0]) == kept, "a finished trial was trained again"
    rows = _check_outputs(out, trials=2, episodes=8)
    resumed = next(r for r in rows if r["trial_id"] == running[0].name)
    evaluations = list(csv.DictReader(open(Path(resumed["run_dir"]) / "evaluations.csv")))
    assert [int(r["episode"]) for r in evaluations] == [4, 8]  # continued from its checkpoint, nothing twice
    episodes = list(csv.DictReader(open(Path(resumed["run_dir"]) / "episodes.csv")))
    assert [int(r["episode"]) for r in episodes] == list(range(1, 9))
    plan = json.loads((out / "sweep_plan.json").read_text())
    assert [s["resumed"] for s in plan["sessions"]] == [False, True]
    data = json.loads((tmp_path / "sweep.json").read_text())
    scores = [r["score"] for r in data["rows"]]  # ranked, best first
    assert scores == sorted(scores, reverse=True) and len(scores) == 2
    assert data["best"]["trial_id"] == data["rows"][0]["trial_id"] and data["wall_time_s"] > 0
    _eval_works(out / "best.safetensors")
    _eval_works(Path(rows[0]["run_dir"]))  # a trial's run directory, as `eval --policy DIR`
    assert not _wait_for_no_ray(root), "embedded Ray outlived its driver"
