"""Resuming a run: no pickle is loaded from a checkpoint, a kill -9 at any moment loses no bookkeeping and
leaves the files of an uninterrupted run, and options ``--resume`` would ignore are refused."""

import csv
import json
import pickle
import signal
import sys
from pathlib import Path

import forked
import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml

import autoscoop  # noqa: F401
from autoscoop.agents.algorithms import ALGORITHMS
from autoscoop.agents.policy_files import sha256_of
from autoscoop.cli import main
from autoscoop.core.config import ScoopConfig, save_yaml
from autoscoop.training.model_state import load_model_state, save_model_state

FAST = ["--recipe", "paper", "--set", "pile.variants=2", "--no-progress"]
RUN = ["--episodes", "8", "--checkpoint-every", "3", "--eval-every", "2", "--eval-episodes", "1", *FAST]
"""8 episodes, checkpoints after 3 and 6, evaluations at 2, 4, 6 and 8."""

KILL_DRIVER = """
import os, signal, sys
from autoscoop.training import callbacks
original = callbacks.EpisodeLogger.end_episode
def end_episode(self, env_index, info):
    original(self, env_index, info)
    if self.done == int(sys.argv[1]):
        os.kill(os.getpid(), signal.SIGKILL)  # kill -9 right after this episode's row (and evaluation)
callbacks.EpisodeLogger.end_episode = end_episode
from autoscoop.cli import main
sys.exit(main(sys.argv[2:]))
"""


class _Exploit:
    """A pickle payload: unpickling it creates a file."""

    def __init__(self, target: Path) -> None:
        self.target = target

    def __reduce__(self):
        return (Path.touch, (Path(self.target),))


def _kill_9_after(episode: int, out: Path, tmp_path: Path) -> None:
    """Train ``RUN`` into ``out`` in another process that kill -9s itself right after ``episode``."""
    done = forked.run([sys.executable, "-c", KILL_DRIVER, str(episode), "train", *RUN, "--out", str(out)],
                      capture_output=True, text=True, timeout=300)
    assert done.returncode == -signal.SIGKILL, done.stderr[-3000:]


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def _form(run_dir: Path) -> dict:
    """What must not differ between an uninterrupted run and a resumed one: files, CSV rows, run.json keys."""
    episodes, evaluations = _rows(run_dir / "episodes.csv"), _rows(run_dir / "evaluations.csv")
    return {"files": sorted(p.name for p in run_dir.iterdir()),
            "evaluated": sorted(p.name for p in (run_dir / "evaluated").iterdir()),
            "episodes": [int(r["episode"]) for r in episodes],
            "episode_columns": sorted({tuple(r) for r in episodes}),
            "complete_rows": all(None not in r.values() and None not in r for r in episodes + evaluations),
            "evaluations": [int(r["episode"]) for r in evaluations],
            "run_json_keys": sorted(json.loads((run_dir / "run.json").read_text()))}


def _check_best_is_the_first_of_the_best_scores(run_dir: Path) -> dict:
    """The kept policy is the first evaluation of the highest score (replaced only by a strictly better one)."""
    info = json.loads((run_dir / "run.json").read_text())
    evaluations = _rows(run_dir / "evaluations.csv")
    best = max(float(r["delivered_fill"]) for r in evaluations)
    first = next(int(r["episode"]) for r in evaluations if float(r["delivered_fill"]) == best)
    assert info["best_score"] == pytest.approx(best) and info["best_episode"] == first
    assert json.loads((run_dir / "policy.json").read_text())["selected_at_episode"] == first
    assert sha256_of(run_dir / "policy.safetensors") == \
        sha256_of(run_dir / "evaluated" / f"episode_{first:05d}.safetensors")
    return info


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The form of an uninterrupted run of ``RUN``."""
    out = tmp_path_factory.mktemp("reference") / "run"
    assert main(["train", *RUN, "--out", str(out)]) == 0
    _check_best_is_the_first_of_the_best_scores(out)
    return _form(out)


@pytest.fixture
def resumed_from(monkeypatch):
    """The episode each ``resume`` in the test continued from (0: started again)."""
    from autoscoop.training import run as train_mod

    seen = []
    original = train_mod.train_model

    def spy(run_dir, config, spec, info, done, model, progress, **kwargs):
        seen.append(done)
        return original(run_dir, config, spec, info, done, model, progress, **kwargs)

    monkeypatch.setattr(train_mod, "train_model", spy)
    return seen


# --- item 3: no pickle --------------------------------------------------------------------------------


def _small_model(algo: str, seed: int):
    from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise

    env = gym.make("autoscoop/Scoop-v1", **{"pile.variants": 1})
    if algo == "ppo":
        return ALGORITHMS[algo]("MlpPolicy", env, n_steps=32, batch_size=16, n_epochs=1, seed=seed, device="cpu")
    kwargs = {"learning_starts": 16, "buffer_size": 300, "batch_size": 16}
    if algo in ("ddpg", "td3"):
        noise_cls = OrnsteinUhlenbeckActionNoise if algo == "ddpg" else NormalActionNoise
        kwargs["action_noise"] = noise_cls(np.zeros(3), np.full(3, 0.2))
    return ALGORITHMS[algo]("MlpPolicy", env, seed=seed, device="cpu", **kwargs)


def _flat(value, prefix=""):
    """A nested state dict as ``{path: tensor or value}``."""
    if isinstance(value, dict):
        return {k: v for key, item in value.items() for k, v in _flat(item, f"{prefix}/{key}").items()}
    if isinstance(value, (list, tuple)):
        return {k: v for i, item in enumerate(value) for k, v in _flat(item, f"{prefix}/{i}").items()}
    return {prefix: value}


def _copy(state_dicts):
    """A flat copy of a model's state dicts (their tensors change as it learns)."""
    return {k: v.clone() if isinstance(v, torch.Tensor) else v for k, v in _flat(state_dicts).items()}


@pytest.fixture
def one_thread():
    """One torch thread, as training runs (many threads on a busy machine are 50 times slower)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.mark.parametrize("algo", ["ddpg", "td3", "sac", "tqc", "ppo"])
def test_model_state_round_trips_through_safetensors_npz_and_json(algo, tmp_path, one_thread):
    trained = _small_model(algo, seed=0)
    trained.learn(64)
    state = json.loads(json.dumps(save_model_state(trained, tmp_path)))  # all of it JSON
    assert sorted(p.name for p in tmp_path.iterdir()) == \
        (["tensors.safetensors"] if algo == "ppo" else ["replay_buffer.npz", "tensors.safetensors"])
    fresh = _small_model(algo, seed=1)
    load_model_state(fresh, tmp_path, state)

    want, got = _flat(trained.get_parameters()), _flat(fresh.get_parameters())
    assert want.keys() == got.keys()
    assert any("optimizer/state" in key for key in want)  # the optimizers' moments are there
    for key, value in want.items():
        if isinstance(value, torch.Tensor):
            assert torch.equal(value, got[key]), key
        else:
            assert value == got[key], key
    for name in ("num_timesteps", "_n_updates", "_episode_num", "_current_progress_remaining"):
        assert getattr(fresh, name) == getattr(trained, name) and (name != "_n_updates" or trained._n_updates > 0)
    if algo in ("sac", "tqc"):
        assert torch.equal(fresh.log_ent_coef, trained.log_ent_coef)
    if algo != "ppo":
        old, new = trained.replay_buffer, fresh.replay_buffer
        assert (new.pos, new.full) == (old.pos, old.full) and new.pos > 0
        for name in ("observations", "next_observations", "actions", "rewards", "dones", "timeouts"):
            np.testing.assert_array_equal(getattr(new, name), getattr(old, name), err_msg=name)
    if algo in ("ddpg", "td3"):
        assert np.array_equal(fresh.action_noise._sigma, trained.action_noise._sigma)
    if algo == "ddpg":
        np.testing.assert_array_equal(fresh.action_noise.noise_prev, trained.action_noise.noise_prev)


def _crashed_run(tmp_path: Path, monkeypatch, crash_after: int = 5, hyper: dict | None = None) -> Path:
    """A run of ``RUN`` that stopped (an exception) after ``crash_after`` episodes, its checkpoint after 3."""
    from autoscoop.training import run as train_mod
    from autoscoop.training.callbacks import EpisodeLogger

    out = tmp_path / "run"
    original = EpisodeLogger.end_episode

    def crash(self, env_index, info):
        original(self, env_index, info)
        if self.done == crash_after:
            raise KeyboardInterrupt("simulated crash")

    monkeypatch.setattr(EpisodeLogger, "end_episode", crash)
    with pytest.raises(KeyboardInterrupt):
        train_mod.train(train_mod.TrainArgs(episodes=8, checkpoint_every=3, eval_every=2, eval_episodes=1, out=out,
                                            progress=False, overrides={"pile.variants": 2}, hyper=hyper or {},
                                            recipe="paper"))
    monkeypatch.setattr(EpisodeLogger, "end_episode", original)
    return out


def test_resume_loads_the_checkpoints_tensors_counters_and_buffer_exactly(tmp_path, monkeypatch):
    from stable_baselines3 import DDPG

    from autoscoop.training import callbacks

    saved = {}
    original_save = callbacks.save_checkpoint

    def keep_a_copy(model, run_dir, bookkeeping, algo):
        saved.update(params=_copy(model.get_parameters()),
                     timesteps=model.num_timesteps, updates=model._n_updates,
                     buffer=model.replay_buffer.observations[:model.replay_buffer.pos].copy())
        original_save(model, run_dir, bookkeeping, algo)

    monkeypatch.setattr(callbacks, "save_checkpoint", keep_a_copy)
    out = _crashed_run(tmp_path, monkeypatch, hyper={"hyperparams.learning_starts": "40"})  # it learns before 3
    monkeypatch.setattr(callbacks, "save_checkpoint", original_save)
    assert saved["updates"] > 0
    assert sorted(p.name for p in (out / "checkpoint").iterdir()) == \
        ["best", "replay_buffer.npz", "state.json", "tensors.safetensors"]  # no model.zip, no .pkl
    seen = {}
    original_learn = DDPG.learn

    def spy_learn(self, *args, **kwargs):
        seen.update(params=_copy(self.get_parameters()), timesteps=self.num_timesteps, updates=self._n_updates,
                    buffer=self.replay_buffer.observations[:self.replay_buffer.pos].copy())
        return original_learn(self, *args, **kwargs)

    monkeypatch.setattr(DDPG, "learn", spy_learn)
    assert main(["train", "--resume", str(out), "--no-progress"]) == 0
    assert (seen["timesteps"], seen["updates"]) == (saved["timesteps"], saved["updates"])
    np.testing.assert_array_equal(seen["buffer"], saved["buffer"])
    assert seen["params"].keys() == saved["params"].keys()
    for key, value in saved["params"].items():
        assert torch.equal(value, seen["params"][key]) if isinstance(value, torch.Tensor) else \
            value == seen["params"][key], key


@pytest.mark.parametrize("name", ["replay_buffer.pkl", "model.zip", "best/extra.pkl"])
def test_a_crafted_pickle_in_the_checkpoint_is_refused_and_never_runs(name, tmp_path, monkeypatch, capsys):
    out = _crashed_run(tmp_path, monkeypatch)
    marker = tmp_path / "pwned"
    (out / "checkpoint" / name).write_bytes(pickle.dumps(_Exploit(marker)))
    episodes_before = (out / "episodes.csv").read_text()
    assert main(["train", "--resume", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert str(out / "checkpoint" / name) in err and "not opened" in err and "Traceback" not in err
    assert not marker.exists()
    assert (out / "episodes.csv").read_text() == episodes_before  # nothing was changed before the refusal
    (out / "checkpoint" / name).unlink()
    assert main(["train", "--resume", str(out), "--no-progress"]) == 0
    assert not marker.exists()


def test_a_pickled_array_in_the_replay_buffer_file_is_refused_even_with_its_hash_rewritten(tmp_path, monkeypatch,
                                                                                          capsys):
    out = _crashed_run(tmp_path, monkeypatch)
    marker = tmp_path / "pwned"
    checkpoint = out / "checkpoint"
    with open(checkpoint / "replay_buffer.npz", "wb") as handle:
        np.savez(handle, observations=np.array([_Exploit(marker)], dtype=object), pos=np.int64(0),
                 full=np.bool_(False))
    state = json.loads((checkpoint / "state.json").read_text())
    state["files"]["replay_buffer.npz"] = sha256_of(checkpoint / "replay_buffer.npz")  # as an attacker would
    (checkpoint / "state.json").write_text(json.dumps(state))
    assert main(["train", "--resume", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert str(checkpoint / "replay_buffer.npz") in err and "Traceback" not in err
    assert not marker.exists()


def test_a_checkpoint_of_the_old_pickle_format_is_refused_with_a_way_out(tmp_path, monkeypatch, capsys):
    out = _crashed_run(tmp_path, monkeypatch)
    marker = tmp_path / "pwned"
    checkpoint = out / "checkpoint"
    for path in checkpoint.iterdir():
        if path.is_file():
            path.unlink()
    (checkpoint / "replay_buffer.pkl").write_bytes(pickle.dumps(_Exploit(marker)))
    (checkpoint / "state.json").write_text(json.dumps({"episodes_done": 3, "num_timesteps": 90,
                                                       "model_sha256": "0" * 64}))
    assert main(["train", "--resume", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "checkpoint format None" in err and f"remove {checkpoint}" in err and not marker.exists()


# --- item 4: kill -9 -----------------------------------------------------------------------------------


def test_kill_9_after_a_checkpoint_keeps_the_bookkeeping_and_resumes_to_an_uninterrupted_runs_files(
        tmp_path, reference, resumed_from):
    out = tmp_path / "run"
    _kill_9_after(5, out, tmp_path)  # checkpoint after 3; evaluations at 2 and 4 done
    state = json.loads((out / "checkpoint" / "state.json").read_text())
    assert (state["episodes_done"], state["evaluations_done"]) == (3, 1)
    killed = json.loads((out / "run.json").read_text())
    assert killed["status"] == "running" and killed["wall_s"] == round(state["wall_s"], 1) > 0
    assert (killed["best_score"], killed["best_episode"]) == (state["best_score"], state["best_episode"])
    # a kill during a later evaluation's write: the kept policy's files are half-written
    for name in ("policy.zip", "policy.safetensors", "policy.json"):
        (out / name).write_bytes(b"half")
    assert main(["train", "--resume", str(out), "--no-progress"]) == 0
    assert resumed_from == [3]
    assert _form(out) == reference
    info = _check_best_is_the_first_of_the_best_scores(out)
    assert info["wall_s"] >= state["wall_s"]  # the earlier part counted on
    wall = [float(r["wall_s"]) for r in _rows(out / "episodes.csv")]
    assert wall == sorted(wall)  # one clock across the resume


def test_kill_9_before_the_first_checkpoint_restarts_without_duplicate_rows(tmp_path, reference, resumed_from):
    out = tmp_path / "run"
    _kill_9_after(2, out, tmp_path)  # the evaluation at 2 is written, no checkpoint yet
    assert [int(r["episode"]) for r in _rows(out / "evaluations.csv")] == [2]
    assert not (out / "checkpoint").exists()
    assert main(["train", "--resume", str(out), "--no-progress"]) == 0
    assert resumed_from == [0]
    assert _form(out) == reference
    _check_best_is_the_first_of_the_best_scores(out)


def test_kill_9_while_checkpoints_are_swapped_resumes_from_the_newest(tmp_path, reference, resumed_from):
    out = tmp_path / "run"
    _kill_9_after(7, out, tmp_path)  # checkpoints after 3 and 6
    # as a kill between `checkpoint -> checkpoint.old` and `checkpoint.tmp -> checkpoint` leaves it
    (out / "checkpoint").rename(out / "checkpoint.tmp")
    assert main(["train", "--resume", str(out), "--no-progress"]) == 0
    assert resumed_from == [6]
    assert _form(out) == reference
    assert not any((out / name).exists() for name in ("checkpoint", "checkpoint.tmp", "checkpoint.old"))


# --- item 3 (options): what --resume would ignore is refused -----------------------------------------------


@pytest.fixture
def interrupted(tmp_path, monkeypatch):
    """An interrupted ddpg run (run.json, config.yaml, hyperparams.yaml) and the list of resumes that got as
    far as training (``train_model`` replaced: none trains)."""
    from autoscoop.training import run as train_mod
    from autoscoop.training.settings import load_hyperparams

    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "run.json").write_text(json.dumps({"algo": "ddpg", "seed": 0, "episodes": 8, "n_envs": 1,
                                                  "checkpoint_every": 4, "eval_every": 4, "eval_episodes": 2,
                                                  "demo_episodes": 0, "status": "running", "wall_s": 0.0}))
    save_yaml(ScoopConfig(), run_dir / "config.yaml")
    (run_dir / "hyperparams.yaml").write_text(yaml.safe_dump(load_hyperparams("ddpg")))
    resumed = []
    monkeypatch.setattr(train_mod, "train_model", lambda run_dir, config, spec, info, **kwargs:
                        resumed.append(kwargs["progress"]) or run_dir)
    return run_dir, resumed


@pytest.mark.parametrize("options", [["--set", "pile.angle_deg=28"], ["--config", "c.yaml"],
                                     ["--hyper", "noise.sigma_start=0.05"]])
def test_resume_refuses_settings_it_would_ignore(options, interrupted, capsys):
    run_dir, resumed = interrupted
    assert main(["train", "--resume", str(run_dir), *options]) == 2
    err = capsys.readouterr().err
    assert f"{options[0]} cannot be given with --resume" in err and str(run_dir / "config.yaml") in err
    assert resumed == []


@pytest.mark.parametrize("options", [["--out", "elsewhere"], ["--init", "other-run"]])
def test_resume_refuses_options_of_a_new_run(options, interrupted, capsys):
    run_dir, resumed = interrupted
    assert main(["train", "--resume", str(run_dir), *options]) == 2
    assert f"{options[0]} cannot be given with --resume" in capsys.readouterr().err
    assert resumed == []


@pytest.mark.parametrize("option, value, recorded", [
    ("--algo", "td3", "'ddpg'"), ("--seed", "3", "0"), ("--n-envs", "2", "1"), ("--checkpoint-every", "5", "4"),
    ("--eval-every", "5", "4"), ("--eval-episodes", "5", "2"), ("--demo-episodes", "5", "0")])
def test_resume_refuses_a_recorded_setting_with_another_value(option, value, recorded, interrupted, capsys):
    run_dir, resumed = interrupted
    assert main(["train", "--resume", str(run_dir), option, value]) == 2
    err = capsys.readouterr().err
    assert f"{option} {value} does not match" in err and str(run_dir / "run.json") in err and f"= {recorded}" in err
    assert resumed == []


def test_resume_takes_the_recorded_values_and_no_progress(interrupted):
    run_dir, resumed = interrupted
    assert main(["train", "--resume", str(run_dir), "--algo", "ddpg", "--seed", "0", "--n-envs", "1",
                 "--checkpoint-every", "4", "--eval-every", "4", "--eval-episodes", "2", "--demo-episodes", "0",
                 "--no-progress"]) == 0
    assert main(["train", "--resume", str(run_dir)]) == 0
    assert resumed == [False, True]  # --no-progress honoured


def test_a_new_run_still_gets_the_documented_defaults(tmp_path, monkeypatch):
    from autoscoop.training import run as train_mod

    seen = []
    monkeypatch.setattr(train_mod, "train", lambda args: seen.append(args) or tmp_path)
    assert main(["train"]) == 0
    args = seen[0]
    assert (args.algo, args.recipe, args.episodes, args.seed, args.n_envs, args.checkpoint_every, args.eval_every,
            args.eval_episodes, args.demo_episodes) == ("ddpg", "robot_smooth", 5000, 0, 1, 50, 50, 10, None)
    assert main(["train", "--recipe", "paper"]) == 0  # the paper's recipe, with its own episode count
    assert (seen[1].recipe, seen[1].episodes) == ("paper", 800)


def test_a_run_fine_tuned_from_a_zip_starts_again_only_with_trust(tmp_path, capsys):
    """Killed before its first checkpoint, a run started with ``--init RUN --trust`` loads the zip again: without
    ``--trust`` the resume is refused and changes no file; with it, the run starts again and finishes."""
    source, tuned = tmp_path / "source", tmp_path / "tuned"
    assert main(["train", "--episodes", "2", "--eval-every", "2", "--eval-episodes", "1", "--out", str(source),
                 *FAST]) == 0
    assert main(["train", "--init", str(source), "--trust", "--episodes", "2", "--eval-every", "2",
                 "--eval-episodes", "1", "--out", str(tuned), *FAST]) == 0
    info = json.loads((tuned / "run.json").read_text())
    assert Path(info["init_from"]).name == "policy.zip"
    (tuned / "run.json").write_text(json.dumps({**info, "status": "running"}))  # as if killed before a checkpoint
    before = {path.name: path.read_bytes() for path in tuned.iterdir() if path.is_file()}
    capsys.readouterr()
    assert main(["train", "--resume", str(tuned), "--no-progress"]) == 2
    assert "--trust" in capsys.readouterr().err
    assert {path.name: path.read_bytes() for path in tuned.iterdir() if path.is_file()} == before
    assert main(["train", "--resume", str(tuned), "--trust", "--no-progress"]) == 0
    assert json.loads((tuned / "run.json").read_text())["status"] == "finished"
