"""The actor's short history: one builder for training, evaluation, ONNX and the ROS node, and parity between them."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from autoscoop.core.config import ScoopConfig
from autoscoop.core.state import (
    ACTION_SIZE,
    STATE_SIZE,
    ActorInputHistory,
    actor_input_size,
    history_steps_for_input,
)
from autoscoop.envs.history import ActorInputObservation
from autoscoop.envs.privileged import PRIVILEGED_SIZE, PrivilegedObservation
from autoscoop.envs.scoop import make_scoop_env

SMALL = {"pile.variants": 2}


def test_history_of_one_is_the_state_alone():
    history = ActorInputHistory(1)
    state = np.arange(STATE_SIZE, dtype=np.float32)
    np.testing.assert_array_equal(history.observe(state), state)
    history.acted(np.ones(ACTION_SIZE))
    np.testing.assert_array_equal(history.observe(state + 1), state + 1)
    assert actor_input_size(1) == STATE_SIZE and history_steps_for_input(STATE_SIZE) == 1


def test_history_is_newest_first_and_starts_from_the_first_state_and_no_command():
    history = ActorInputHistory(3)
    s = [np.full(STATE_SIZE, float(k), dtype=np.float32) for k in range(4)]
    first = history.observe(s[0])
    assert first.shape == (3 * (STATE_SIZE + ACTION_SIZE),) == (actor_input_size(3),)
    np.testing.assert_array_equal(first[:3 * STATE_SIZE], np.zeros(3 * STATE_SIZE))  # s0 three times
    np.testing.assert_array_equal(first[3 * STATE_SIZE:], np.zeros(3 * ACTION_SIZE))  # standing still
    history.acted(np.array([0.5, -2.0, 0.1]))  # clipped as the robot applies it
    history.observe(s[1])
    history.acted(np.array([0.2, 0.3, 0.4]))
    third = history.observe(s[2])
    states = third[:3 * STATE_SIZE].reshape(3, STATE_SIZE)[:, 0]
    actions = third[3 * STATE_SIZE:].reshape(3, ACTION_SIZE)
    np.testing.assert_array_equal(states, [2.0, 1.0, 0.0])
    np.testing.assert_allclose(actions, [[0.2, 0.3, 0.4], [0.5, -1.0, 0.1], [0.0, 0.0, 0.0]])
    history.reset()
    np.testing.assert_array_equal(history.observe(s[3])[:STATE_SIZE * 3], np.full(STATE_SIZE * 3, 3.0))
    assert history_steps_for_input(actor_input_size(3)) == 3
    with pytest.raises(ValueError, match="neither"):
        history_steps_for_input(20)


def test_the_training_wrapper_builds_the_history_from_the_env_states_and_the_actions_sent():
    config = ScoopConfig().with_overrides(SMALL)
    plain = make_scoop_env(config)
    wrapped = PrivilegedObservation(ActorInputObservation(make_scoop_env(config), 2))
    size = actor_input_size(2)
    assert wrapped.observation_space.shape == (size + PRIVILEGED_SIZE,)
    state, _ = plain.reset(seed=3)
    obs, _ = wrapped.reset(seed=3)
    np.testing.assert_array_equal(obs[:STATE_SIZE], state)
    action = np.array([1.0, 0.1, -0.1], dtype=np.float32)
    before = state
    state, *_ = plain.step(action)
    obs, *_ = wrapped.step(action)
    np.testing.assert_array_equal(obs[:STATE_SIZE], state)
    np.testing.assert_array_equal(obs[STATE_SIZE:2 * STATE_SIZE], before)
    np.testing.assert_allclose(obs[2 * STATE_SIZE:2 * STATE_SIZE + ACTION_SIZE], action)


@pytest.fixture(scope="module")
def history_run(tmp_path_factory):
    """A tiny training run of an actor that reads 3 states and commands, with an asymmetric critic."""
    from autoscoop.training import run as train_mod
    from autoscoop.training import settings

    original = settings.load_recipe
    out = tmp_path_factory.mktemp("history") / "run"
    patch = pytest.MonkeyPatch()
    patch.setattr(train_mod, "load_recipe", lambda algo, recipe: {**original(algo, "paper"), "privileged_critic": True,
                                                                  "history_steps": 3, "demo_episodes": 1})
    try:
        train_mod.train(train_mod.TrainArgs(episodes=3, out=out, progress=False, overrides=SMALL, eval_every=3,
                                            eval_episodes=1, checkpoint_every=3))
    finally:
        patch.undo()
    return out


def test_a_history_actor_is_saved_with_its_history_and_acts_like_the_learner(history_run):
    from stable_baselines3 import DDPG

    from autoscoop.agents.policy_files import ActorPolicy
    from autoscoop.core.config import from_dict
    from autoscoop.training.factories import make_training_env

    meta = json.loads((history_run / "policy.json").read_text())
    assert meta["history_steps"] == 3
    policy = ActorPolicy(history_run / "policy.safetensors")
    model = DDPG.load(history_run / "policy.zip", device="cpu")
    import yaml

    env = make_training_env(from_dict(yaml.safe_load((history_run / "config.yaml").read_text())), privileged=True,
                            history=3)
    obs, _ = env.reset(seed=11)
    policy.reset()
    for _ in range(8):  # the safe file on the raw state == the learner on its wrapped observation
        learner, _ = model.predict(obs, deterministic=True)
        np.testing.assert_allclose(policy.act(obs[:STATE_SIZE]), learner, atol=1e-5)
        obs, _, terminated, truncated, _ = env.step(learner)
        if terminated or truncated:
            break


def test_a_history_actor_exports_to_onnx_and_the_runner_builds_the_same_input(history_run, tmp_path):
    pytest.importorskip("onnxruntime")
    from autoscoop.agents.onnx_policy import OnnxPolicy
    from autoscoop.agents.policy_files import ActorPolicy
    from autoscoop.deploy.export import check_parity, export_onnx, random_actor_inputs

    policy = ActorPolicy(history_run / "policy.safetensors")
    path = export_onnx(policy.actor, tmp_path / "history.onnx", {"state_frame": policy.state_frame})
    report = check_parity(policy.actor, path, random_actor_inputs(500, 3, seed=2), timing_steps=10)
    assert report["passed"], report
    runner = OnnxPolicy(path)
    assert runner.metadata["history_steps"] == "3"
    env = make_scoop_env(ScoopConfig().with_overrides({**SMALL, "sensor.level_with_imu": True}))
    state, _ = env.reset(seed=2)
    policy.reset()
    runner.reset()
    for _ in range(8):
        action = policy.act(state)
        np.testing.assert_allclose(runner.act(state), action, atol=5e-5)
        state, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            break


def test_a_history_actor_network_ignores_the_privileged_numbers():
    from stable_baselines3 import DDPG

    from autoscoop.agents.sb3_policies import PaperPolicy

    env = PrivilegedObservation(ActorInputObservation(make_scoop_env(ScoopConfig().with_overrides(SMALL)), 2))
    model = DDPG(PaperPolicy, env, buffer_size=100, policy_kwargs={"history_steps": 2})
    size = actor_input_size(2)
    obs = torch.as_tensor(np.random.default_rng(0).normal(size=(4, size + PRIVILEGED_SIZE)).astype(np.float32))
    other = obs.clone()
    other[:, size:] += 5.0
    with torch.no_grad():
        assert torch.equal(model.policy.actor(obs), model.policy.actor(other))
        assert not torch.equal(model.policy.actor(obs), model.policy.actor(obs + 0.5))


def test_a_sidecar_with_a_bad_history_is_refused(history_run, tmp_path):
    import shutil

    from autoscoop.agents.policy_files import PolicyFileError, load_actor

    for name in ("policy.safetensors", "policy.json"):
        shutil.copy(history_run / name, tmp_path / name)
    meta = json.loads((tmp_path / "policy.json").read_text())
    meta["history_steps"] = 0
    (tmp_path / "policy.json").write_text(json.dumps(meta))
    with pytest.raises(PolicyFileError, match="history_steps"):
        load_actor(tmp_path / "policy.safetensors")
    meta["history_steps"] = 2  # the weights read 3 states and commands
    (tmp_path / "policy.json").write_text(json.dumps(meta))
    with pytest.raises(PolicyFileError, match="do not fit"):
        load_actor(tmp_path / "policy.safetensors")


def test_the_ros_controller_core_feeds_a_history_actor_a_fresh_history_each_scoop(history_run):
    from autoscoop.agents.policy_files import ActorPolicy
    from autoscoop.deploy.controller import ControllerCore
    from autoscoop.deploy.robot_config import RobotNodeConfig
    from autoscoop.deploy.sim_bridge import SimBridge, run_without_ros

    policy = ActorPolicy(history_run / "policy.safetensors")
    inputs: list[np.ndarray] = []
    forward = policy.actor.forward
    policy.actor.forward = lambda x: (inputs.append(x.numpy().copy()), forward(x))[1]
    task = ScoopConfig().with_overrides({"pile.variants": 1, "sensor.level_with_imu": True})
    core = ControllerCore(RobotNodeConfig(), policy, task)
    bridge = SimBridge(task)
    starts = []
    for seed in (0, 1):
        starts.append(len(inputs))
        run_without_ros(bridge, core, seed=seed)
    bridge.close()
    size = 3 * STATE_SIZE
    for start in starts:  # each scoop starts still: its first state thrice, no command before it
        first = inputs[start][0]
        np.testing.assert_array_equal(first[size:], np.zeros(3 * ACTION_SIZE))
        np.testing.assert_array_equal(first[:STATE_SIZE], first[STATE_SIZE:2 * STATE_SIZE])
    second = inputs[starts[0] + 1][0]  # the next input carries the command the core sent
    assert np.any(second[size:size + ACTION_SIZE] != 0.0)
