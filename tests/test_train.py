"""Training: the paper's networks, safe policy files, the train command, resume, refusing pickles."""

import csv
import json
import os
import pickle
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import forked
import gymnasium as gym
import numpy as np
import pytest
import torch
from torch import nn

import autoscoop  # noqa: F401
from autoscoop.agents.loading import PolicyError, load_policy
from autoscoop.agents.networks import PaperActor
from autoscoop.agents.policy_files import ActorPolicy, PolicyFileError, save_actor
from autoscoop.cli import main
from autoscoop.core.config import ScoopConfig

FAST = ["--recipe", "paper", "--set", "pile.variants=2", "--no-progress"]
"""the paper's recipe (no demonstrations, no selection) on a small pile: quick runs."""


def linear_sizes(module: nn.Module) -> list[tuple[int, int]]:
    return [(m.in_features, m.out_features) for m in module.modules() if isinstance(m, nn.Linear)]


def test_paper_policy_layer_sizes_and_merge_point():
    from stable_baselines3 import DDPG

    from autoscoop.agents.sb3_policies import PaperPolicy

    model = DDPG(PaperPolicy, gym.make("autoscoop/Scoop-v1", **{"pile.variants": 1}), buffer_size=100)
    actor, critic = model.policy.actor, model.policy.critic
    assert linear_sizes(actor) == [(12, 100), (100, 80), (80, 60), (60, 3)]
    assert [m.normalized_shape for m in actor.modules() if isinstance(m, nn.LayerNorm)] == [(100,), (80,), (60,)]
    assert isinstance(actor.mu[-1], nn.Tanh)
    # the action (3) joins after the critic's first layer: 12 -> 100, then 100 + 3 -> 80
    assert linear_sizes(critic) == [(12, 100), (103, 80), (80, 60), (60, 1)]
    assert len([m for m in critic.modules() if isinstance(m, nn.LayerNorm)]) == 3


def test_safe_file_round_trip_gives_the_same_actions(tmp_path):
    torch.manual_seed(0)
    actor = PaperActor()
    path = save_actor(actor, tmp_path / "actor")
    loaded = ActorPolicy(path)
    states = np.random.default_rng(0).normal(size=(256, 12)).astype(np.float32)
    with torch.no_grad():
        expected = actor(torch.as_tensor(states)).numpy()
    got = np.stack([loaded.act(s) for s in states])
    assert np.abs(got - expected).max() <= 1e-6


def test_tampered_weights_are_refused(tmp_path):
    path = save_actor(PaperActor(), tmp_path / "actor")
    data = bytearray(path.read_bytes())
    data[-1] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.raises(PolicyFileError, match="SHA-256"):
        ActorPolicy(path)


def test_train_command_smoke_run_writes_the_run_directory(tmp_path):
    out = tmp_path / "run"
    assert main(["train", "--episodes", "8", "--checkpoint-every", "4", "--eval-every", "4", "--eval-episodes", "2",
                 "--out", str(out), *FAST]) == 0
    info = json.loads((out / "run.json").read_text())
    assert info["status"] == "finished" and info["seed"] == 0 and info["autoscoop_version"]
    rows = list(csv.DictReader(open(out / "episodes.csv")))
    assert len(rows) == 8 and {"reward", "fill_factor", "cycle_time_s", "success"} <= set(rows[0])
    for name in ("config.yaml", "hyperparams.yaml", "policy.zip", "policy.safetensors", "policy.json",
                 "last.safetensors", "learning_curve.png", "evaluations.csv"):
        assert (out / name).is_file(), name
    evaluations = list(csv.DictReader(open(out / "evaluations.csv")))
    assert [int(r["episode"]) for r in evaluations] == [4, 8]
    best = max(float(r["delivered_fill"]) for r in evaluations)
    assert info["best_score"] == pytest.approx(best)
    assert json.loads((out / "policy.json").read_text())["selected_at_episode"] == info["best_episode"]
    assert any((out / "tb").rglob("events.out.tfevents.*"))
    policy = load_policy(str(out), ScoopConfig())
    assert policy.act(np.zeros(12, dtype=np.float32)).shape == (3,)
    # the kept policy as ONNX beside it, checked, and the whole command's time (training is a part of it)
    assert info["export"]["onnx"] == "policy.onnx" and info["export"]["passed"]
    onnx = load_policy(str(out / "policy.onnx"), ScoopConfig())
    np.testing.assert_allclose(onnx.act(np.zeros(12, dtype=np.float32)), policy.act(np.zeros(12, dtype=np.float32)),
                               atol=5e-5)
    assert info["command_wall_s"] > info["wall_s"] > 0


def test_resume_continues_steps_and_keeps_the_replay_buffer(tmp_path, monkeypatch):
    from stable_baselines3 import DDPG

    from autoscoop.training import run as train_mod
    from autoscoop.training.callbacks import EpisodeLogger

    out = tmp_path / "run"
    original = EpisodeLogger.end_episode

    def crash_after_five(self, env_index, info):
        original(self, env_index, info)
        if self.done == 5:
            raise KeyboardInterrupt("simulated crash")

    monkeypatch.setattr(EpisodeLogger, "end_episode", crash_after_five)
    with pytest.raises(KeyboardInterrupt):
        train_mod.train(train_mod.TrainArgs(episodes=8, checkpoint_every=4, out=out, progress=False, recipe="paper",
                                            overrides={"pile.variants": 2}, eval_every=5, eval_episodes=1))
    state = json.loads((out / "checkpoint" / "state.json").read_text())
    assert state["episodes_done"] == 4
    # no pickle to load: the only zip is the best policy's copy, put back as a file, never opened
    assert {str(p.relative_to(out / "checkpoint")) for p in (out / "checkpoint").rglob("*.*")
            if p.suffix in (".pkl", ".zip", ".pt", ".pth")} <= {"best/policy.zip"}
    with np.load(out / "checkpoint" / "replay_buffer.npz", allow_pickle=False) as saved:  # no pickle in there
        buffer_at_checkpoint = int(saved["pos"])
    assert buffer_at_checkpoint == state["model"]["counters"]["num_timesteps"] > 0

    monkeypatch.setattr(EpisodeLogger, "end_episode", original)
    seen = {}
    original_learn = DDPG.learn

    def spy_learn(self, *args, **kwargs):
        seen["start_timesteps"] = self.num_timesteps
        seen["start_buffer"] = self.replay_buffer.size()
        return original_learn(self, *args, **kwargs)

    monkeypatch.setattr(DDPG, "learn", spy_learn)
    train_mod.resume(out, progress=False)
    assert seen["start_timesteps"] == state["model"]["counters"]["num_timesteps"]
    assert seen["start_buffer"] == buffer_at_checkpoint
    rows = list(csv.DictReader(open(out / "episodes.csv")))
    assert [int(r["episode"]) for r in rows] == list(range(1, 9))
    assert json.loads((out / "run.json").read_text())["status"] == "finished"
    # the evaluation at episode 5 came after the checkpoint: it is run again, and listed once
    assert [int(r["episode"]) for r in csv.DictReader(open(out / "evaluations.csv"))] == [5, 8]


def test_kill_9_loses_at_most_one_checkpoint_interval(tmp_path):
    out = tmp_path / "run"
    command = [sys.executable, "-m", "autoscoop.cli", "train", "--episodes", "24", "--checkpoint-every", "3",
               "--out", str(out), *FAST]
    process = forked.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and not (out / "checkpoint" / "state.json").exists():
        time.sleep(0.2)
    time.sleep(1.0)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    rows_before = len(list(csv.DictReader(open(out / "episodes.csv"))))
    done = json.loads((out / "checkpoint" / "state.json").read_text())["episodes_done"]
    assert rows_before - done <= 3 + 1
    run = forked.run([sys.executable, "-m", "autoscoop.cli", "train", "--resume", str(out), "--no-progress"],
                     capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    rows = list(csv.DictReader(open(out / "episodes.csv")))
    assert [int(r["episode"]) for r in rows] == list(range(1, 25))


class _Exploit:
    """A pickle payload: unpickling it would create a file."""

    def __init__(self, target: str) -> None:
        self.target = target

    def __reduce__(self):
        return (Path.touch, (Path(self.target),))


def test_a_zip_with_a_pickle_payload_is_refused_without_trust(tmp_path):
    marker = tmp_path / "pwned"
    archive = tmp_path / "policy.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        zf.writestr("data", json.dumps({"policy_class": {":serialized:": pickle.dumps(_Exploit(str(marker))).hex()}}))
        zf.writestr("pytorch_variables.pth", pickle.dumps(_Exploit(str(marker))))
    with pytest.raises(PolicyError, match="--trust"):
        load_policy(str(archive), ScoopConfig())
    assert not marker.exists()
    assert main(["eval", "--policy", str(archive), "--episodes", "1"]) == 2
    assert not marker.exists()


def test_init_fine_tunes_from_a_finished_run_and_checks_what_it_loads(tmp_path):
    source, tuned = tmp_path / "source", tmp_path / "tuned"
    assert main(["train", "--episodes", "3", "--eval-every", "3", "--eval-episodes", "1", "--out", str(source),
                 *FAST]) == 0
    assert main(["train", "--init", str(source), "--episodes", "2", "--eval-every", "2", "--eval-episodes", "1",
                 "--hyper", "noise.sigma_start=0.05", "--hyper", "hyperparams.learning_rate=3e-4",
                 "--out", str(tuned), *FAST]) == 0
    info = json.loads((tuned / "run.json").read_text())
    assert Path(info["init_from"]) == (source / "policy.safetensors").resolve()  # the safe actor: no --trust
    evaluations = [int(r["episode"]) for r in csv.DictReader(open(tuned / "evaluations.csv"))]
    assert evaluations == [0, 2]  # the starting policy is evaluated first
    start = load_policy(str(tuned / "evaluated" / "episode_00000.safetensors"), ScoopConfig())
    original = load_policy(str(source / "policy.safetensors"), ScoopConfig())
    states = np.random.default_rng(0).normal(size=(16, 12)).astype(np.float32)
    np.testing.assert_allclose([start.act(s) for s in states], [original.act(s) for s in states], atol=1e-6)
    hyper = __import__("yaml").safe_load((tuned / "hyperparams.yaml").read_text())
    assert hyper["noise"]["sigma_start"] == 0.05 and hyper["hyperparams"]["learning_rate"] == 3e-4
    # a changed actor file, another algorithm, an unknown setting: refused before training
    with open(source / "policy.safetensors", "ab") as f:
        f.write(b"tampered")
    assert main(["train", "--init", str(source), "--episodes", "1", "--out", str(tmp_path / "a"), *FAST]) == 2
    assert main(["train", "--init", str(tuned), "--algo", "td3", "--episodes", "1", "--out", str(tmp_path / "b"),
                 *FAST]) == 2
    assert main(["train", "--hyper", "hyperparams.lr=1", "--episodes", "1", "--out", str(tmp_path / "c"), *FAST]) == 2
    assert not any((tmp_path / name / "run.json").exists() for name in "abc")


def test_ppo_trains_and_its_run_directory_loads(tmp_path):
    """PPO's Gaussian policy has no paper actor: the run keeps it in its zip, loaded only with trust."""
    out = tmp_path / "ppo"
    assert main(["train", "--algo", "ppo", "--episodes", "3", "--eval-every", "3", "--eval-episodes", "1",
                 "--out", str(out), *FAST]) == 0
    assert (out / "policy.zip").is_file() and not (out / "policy.safetensors").exists()
    with pytest.raises(PolicyError, match="--trust"):
        load_policy(str(out), ScoopConfig())
    policy = load_policy(str(out), ScoopConfig(), trust=True)
    assert policy.act(np.zeros(12, dtype=np.float32)).shape == (3,)


def test_scripted_demonstrations_fill_the_replay_buffer():
    from stable_baselines3.common.buffers import ReplayBuffer

    from autoscoop.agents.demonstrations import add_scripted_demonstrations
    from autoscoop.envs.scoop import make_scoop_env

    config = ScoopConfig().with_overrides({"pile.variants": 1})
    env = make_scoop_env(config)
    buffer = ReplayBuffer(200, env.observation_space, env.action_space, n_envs=2)
    added = add_scripted_demonstrations(buffer, config, episodes=2)
    assert added == buffer.pos * 2 and added >= 20  # two scoops of a few seconds, stored two at a time
    stored = buffer.actions[:buffer.pos].reshape(-1, 3)
    assert np.abs(stored).max() <= 1.0 and np.abs(stored).sum() > 0
    assert buffer.dones[:buffer.pos].sum() >= 1  # the scripted scoop reached the terminal point at least once
    rewards = buffer.rewards[:buffer.pos]
    assert np.isfinite(rewards).all() and rewards.max() > 1.0  # the mass bonus is in there


def test_demonstrations_need_an_off_policy_algorithm(tmp_path):
    from autoscoop.training import run as train_mod

    with pytest.raises(ValueError, match="off-policy"):
        train_mod.train(train_mod.TrainArgs(algo="ppo", episodes=2, out=tmp_path / "run", progress=False,
                                            demo_episodes=1))
    assert not (tmp_path / "run").exists()


def _interrupted_run_json(run_dir: Path) -> None:
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "run.json").write_text(json.dumps({"algo": "ddpg", "seed": 0, "episodes": 8, "n_envs": 1,
                                                  "checkpoint_every": 4, "status": "running", "wall_s": 0.0}))


def _lock_is_free(run_dir: Path) -> bool:
    from filelock import FileLock, Timeout

    lock = FileLock(run_dir / ".lock", timeout=0)
    try:
        lock.acquire()
    except Timeout:
        return False
    lock.release()
    return True


def test_a_run_directory_is_locked_while_a_process_writes_it(tmp_path, monkeypatch, capsys):
    import socket

    from filelock import FileLock

    from autoscoop.training import run as train_mod
    from autoscoop.training.checkpoints import lock_run_dir

    run_dir = tmp_path / "run"
    _interrupted_run_json(run_dir)
    # held by another writer: resume and train into it stop at once, naming the directory and the holder
    with lock_run_dir(run_dir):
        holder = json.loads((run_dir / "lock.json").read_text())
        assert holder["pid"] == os.getpid() and holder["host"] == socket.gethostname() and holder["started"]
        with pytest.raises(ValueError, match="being written by another") as error:
            train_mod.resume(run_dir, progress=False)
        assert str(run_dir) in str(error.value) and f"pid {os.getpid()} on {socket.gethostname()}" in str(error.value)
        assert main(["train", "--resume", str(run_dir), "--no-progress"]) == 2
        assert main(["train", "--episodes", "1", "--out", str(run_dir), *FAST]) == 2
        err = capsys.readouterr().err
        assert err.count("being written by another") == 2 and f"pid {os.getpid()}" in err and str(run_dir) in err
    assert not (run_dir / "lock.json").exists() and _lock_is_free(run_dir)
    # a lock held without a holder file (plain filelock) is refused too
    with FileLock(run_dir / ".lock"):
        with pytest.raises(ValueError, match="holder unknown") as error:
            train_mod.resume(run_dir, progress=False)
        assert str(run_dir) in str(error.value)

    # train holds the lock for the whole run and releases it at the end, and on an exception
    seen = {}

    def fake_run(run_dir, *args, **kwargs):
        seen["pid"] = json.loads((run_dir / "lock.json").read_text())["pid"]
        seen["free"] = _lock_is_free(run_dir)
        if seen.get("crash"):
            raise RuntimeError("simulated failure")
        return run_dir

    monkeypatch.setattr(train_mod, "train_model", fake_run)
    new = tmp_path / "new"
    assert train_mod.train(train_mod.TrainArgs(episodes=1, out=new, progress=False)) == new
    assert seen == {"pid": os.getpid(), "free": False}
    assert not (new / "lock.json").exists() and _lock_is_free(new)
    seen["crash"] = True
    with pytest.raises(RuntimeError, match="simulated"):
        train_mod.train(train_mod.TrainArgs(episodes=1, out=tmp_path / "crash", progress=False))
    assert seen["free"] is False and _lock_is_free(tmp_path / "crash")
    assert not (tmp_path / "crash" / "lock.json").exists()


def test_resume_refuses_episodes(tmp_path, monkeypatch, capsys):
    import yaml

    from autoscoop.core.config import save_yaml
    from autoscoop.training import run as train_mod
    from autoscoop.training.settings import load_hyperparams

    run_dir = tmp_path / "run"
    _interrupted_run_json(run_dir)
    save_yaml(ScoopConfig(), run_dir / "config.yaml")
    (run_dir / "hyperparams.yaml").write_text(yaml.safe_dump(load_hyperparams("ddpg")))
    resumed = []
    monkeypatch.setattr(train_mod, "train_model", lambda run_dir, config, spec, info, **kwargs: resumed.append(info) or run_dir)
    assert main(["train", "--resume", str(run_dir), "--episodes", "20", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "--episodes" in err and "keeps the episode count" in err
    assert not resumed and json.loads((run_dir / "run.json").read_text())["episodes"] == 8
    assert main(["train", "--resume", str(run_dir), "--no-progress"]) == 0  # without it: resumed, with its count
    assert [info["episodes"] for info in resumed] == [8]


def test_resume_of_a_run_json_alone_names_the_missing_files(tmp_path, capsys):
    run_dir = tmp_path / "run"
    _interrupted_run_json(run_dir)
    assert main(["train", "--resume", str(run_dir), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert str(run_dir / "config.yaml") in err and str(run_dir / "hyperparams.yaml") in err
    assert "Traceback" not in err
    (run_dir / "config.yaml").write_text(__import__("yaml").safe_dump({}))
    assert main(["train", "--resume", str(run_dir), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert str(run_dir / "hyperparams.yaml") in err and str(run_dir / "config.yaml") not in err
    assert _lock_is_free(run_dir)  # released after the refusal


def test_recipes_lay_over_the_algorithms_yaml():
    from autoscoop.training.settings import config_at, curriculum_stages, load_hyperparams, load_recipe

    paper = load_recipe("ddpg", "paper")
    assert {k: v for k, v in paper.items() if k not in ("episodes", "recipe")} == load_hyperparams("ddpg")
    robot = load_recipe("td3", "robot")
    assert robot["algo"] == "td3" and robot["demo_episodes"] > 0 and robot["env"]["reward.c_w"] == 50
    stages = curriculum_stages(robot)
    assert stages and all(key.startswith("randomize.") for _, keys in stages for key in keys)
    base = ScoopConfig()
    assert config_at(base, robot, stages[0][0] - 1) == base
    assert config_at(base, robot, stages[0][0]).randomize.preset == "robot"
    # a recipe's sections are laid over the algorithm's key by key: the rest of hyperparams stays
    ddpg = load_hyperparams("ddpg")
    robot_ddpg = load_recipe("ddpg", "robot")
    assert set(robot_ddpg["hyperparams"]) == set(ddpg["hyperparams"])
    assert robot_ddpg["hyperparams"]["gamma"] == ddpg["hyperparams"]["gamma"]
    assert robot_ddpg["noise"] == ddpg["noise"]
    with pytest.raises(ValueError, match="--recipe 'fast'"):
        load_recipe("ddpg", "fast")
    with pytest.raises(ValueError, match="only randomize"):
        curriculum_stages({"curriculum": [{"episode": 3, "set": {"pile.angle_deg": 25}}]})


def test_a_curriculum_switches_the_training_and_evaluation_world(tmp_path, monkeypatch):
    """After the stage's episode the environments draw randomised worlds and the kept policy is chosen again."""
    from autoscoop.training import run as train_mod
    from autoscoop.training import settings

    stage = {"episode": 3, "set": {"randomize.preset": "robot"}}
    original = settings.load_recipe
    monkeypatch.setattr(train_mod, "load_recipe",
                        lambda algo, recipe: {**original(algo, "paper"), "curriculum": [stage]})
    seen: list[dict] = []
    from autoscoop.training.callbacks import EpisodeLogger

    end = EpisodeLogger.end_episode

    def watch(self, env_index, info):
        seen.append(dict(info.get("world") or {}))
        end(self, env_index, info)

    monkeypatch.setattr(EpisodeLogger, "end_episode", watch)
    out = tmp_path / "run"
    train_mod.train(train_mod.TrainArgs(episodes=6, out=out, progress=False, overrides={"pile.variants": 2},
                                        eval_every=3, eval_episodes=1, checkpoint_every=10))
    # each environment had already begun its next episode (SB3 resets at once): episodes 5-6 in drawn worlds
    assert [bool(world) for world in seen] == [False] * 4 + [True] * 2
    rows = list(csv.DictReader(open(out / "evaluations.csv")))
    assert [row["episode"] for row in rows] == ["3", "6"]
    info = json.loads((out / "run.json").read_text())
    assert info["best_episode"] == 6  # chosen again in the randomised world, whatever episode 3 scored


def test_two_environments_without_demonstrations_are_warned_about(tmp_path, capsys):
    """``--n-envs 2`` trains, and says that without scripted scoops it did not learn (README, Speed); with them, no warning."""
    assert main(["train", "--episodes", "2", "--n-envs", "2", "--eval-every", "0", "--out", str(tmp_path / "a"),
                 *FAST]) == 0
    assert "--n-envs 2 without scripted demonstrations" in capsys.readouterr().err
    assert main(["train", "--episodes", "2", "--n-envs", "2", "--eval-every", "0", "--demo-episodes", "1",
                 "--out", str(tmp_path / "b"), *FAST]) == 0
    assert "without scripted demonstrations" not in capsys.readouterr().err


def test_learning_rate_end_lowers_the_learning_rate_linearly_over_the_episodes(tmp_path, monkeypatch):
    """``learning_rate_end``: the optimisers' rate falls from hyperparams.learning_rate to it over the run."""
    from autoscoop.training import run as train_mod
    from autoscoop.training import settings
    from autoscoop.training.callbacks import EpisodeLogger

    original = settings.load_recipe
    spec = original("ddpg", "paper")
    spec = {**spec, "hyperparams": {**spec["hyperparams"], "learning_rate": 1e-3, "learning_starts": 10},
            "learning_rate_end": 1e-4}
    monkeypatch.setattr(train_mod, "load_recipe", lambda algo, recipe: spec)
    rates: list[float] = []
    end = EpisodeLogger.end_episode

    def watch(self, env_index, info):
        end(self, env_index, info)
        self.model.train(gradient_steps=1, batch_size=8)  # the rate SB3 sets before each update
        rates.append(self.model.actor.optimizer.param_groups[0]["lr"])

    monkeypatch.setattr(EpisodeLogger, "end_episode", watch)
    train_mod.train(train_mod.TrainArgs(episodes=4, out=tmp_path / "run", progress=False,
                                        overrides={"pile.variants": 2}, eval_every=0, checkpoint_every=10))
    assert rates == pytest.approx([1e-3 - 0.9e-3 * k / 4 for k in (1, 2, 3, 4)])


@pytest.mark.parametrize("value", [0, -1e-4, 2.0, "fast", True])
def test_a_bad_learning_rate_end_is_refused_by_name(tmp_path, monkeypatch, value):
    from autoscoop.training import run as train_mod
    from autoscoop.training import settings

    original = settings.load_recipe
    monkeypatch.setattr(train_mod, "load_recipe",
                        lambda algo, recipe: {**original(algo, "paper"), "learning_rate_end": value})
    with pytest.raises(ValueError, match="learning_rate_end"):
        train_mod.train(train_mod.TrainArgs(episodes=1, out=tmp_path / "run", progress=False))


def test_train_offers_each_algorithm_of_the_registry_and_no_other(capsys):
    from autoscoop.agents.algorithms import ALGORITHMS
    from autoscoop.training.recipes import algorithm_names

    assert set(algorithm_names()) == set(ALGORITHMS)  # one YAML per class, one class per YAML
    with pytest.raises(SystemExit):
        main(["train", "--algo", "nonesuch"])
    err = capsys.readouterr().err
    assert all(name in err for name in ALGORITHMS)
