"""``autoscoop adapt``: the critic beside a policy, the actor held then slowed, bad input refused before any
simulation, and a small run that writes a run directory, keeps a validated snapshot and resumes after a kill."""

import contextlib
import json
import os
import shutil
import signal
import subprocess
import sys

import forked
import pytest
import torch

from autoscoop.agents.critic_files import critic_into_sb3, critic_path_for, read_critic_sidecar, save_critic
from autoscoop.agents.loading import default_policy_path
from autoscoop.agents.optimizers import HeldAdam
from autoscoop.agents.policy_files import PolicyFileError, sha256_of
from autoscoop.cli import main

TINY = ["--episodes", "6", "--eval-every", "3", "--candidates", "1", "--validation-episodes", "1",
        "--critic-warmup-steps", "20", "--eval-episodes", "1", "--set", "pile.variants=2", "--no-progress",
        "--workers", "1"]
"""6 episodes, two simulators, evaluations at 3 and 6, one snapshot validated beside the start on 1 episode a world."""

KILL_DRIVER = """
import os, signal, sys
from autoscoop.training import callbacks
original = callbacks.EpisodeLogger.end_episode
def end_episode(self, env_index, info):
    original(self, env_index, info)
    if self.done == int(sys.argv[1]):
        os.kill(os.getpid(), signal.SIGKILL)
callbacks.EpisodeLogger.end_episode = end_episode
if __name__ == "__main__":  # the simulators' worker processes import this file again
    from autoscoop.cli import main
    sys.exit(main(sys.argv[2:]))
"""


def test_the_shipped_policy_has_its_critic_beside_it():
    actor = default_policy_path()
    meta = read_critic_sidecar(critic_path_for(actor))
    assert meta["actor_sha256"] == sha256_of(actor)
    assert meta["held_config"]["randomize"]["preset"] == "robot"
    assert meta["config"]["randomize"]["preset"] == "none"
    assert meta["spec"]["privileged_critic"] is True


def test_held_adam_holds_then_moves_at_a_fraction_of_the_rate():
    torch.manual_seed(0)
    held, full = torch.nn.Linear(3, 1), torch.nn.Linear(3, 1)
    full.load_state_dict(held.state_dict())
    start = held.weight.detach().clone()
    slow, fast = HeldAdam(held.parameters(), lr=0.1, hold_steps=2, lr_scale=0.1), torch.optim.Adam(full.parameters(), lr=0.1)
    for step in range(3):
        for net, optimizer in ((held, slow), (full, fast)):
            optimizer.zero_grad()
            net(torch.ones(1, 3)).sum().backward()
            optimizer.step()
        if step < 2:
            assert torch.equal(held.weight, start)  # held
    moved = (held.weight - start).abs().max().item()
    assert 0.009 < moved < 0.011  # Adam's first step is lr: 0.1 x 0.1
    restored = HeldAdam(torch.nn.Linear(3, 1).parameters(), lr=0.1)
    restored.load_state_dict(slow.state_dict())
    assert restored.param_groups[0]["steps_taken"] == 3 and restored.param_groups[0]["lr_scale"] == 0.1


def test_a_critic_file_round_trips_and_a_changed_one_is_refused(tmp_path):
    from autoscoop.training.adapt import AdaptArgs, adapt_model, adapt_source, adapt_spec, adapt_worlds

    source = adapt_source("default")
    target, held = adapt_worlds(source, {"pile.variants": 2})
    spec = adapt_spec(source, AdaptArgs(episodes=2))
    info = {"algo": "ddpg", "seed": 0, "n_envs": 2, "init_from": str(source.actor), "init_sha256": sha256_of(source.actor),
            "adapt": {"critic_from": str(source.critic)}}
    model = adapt_model(tmp_path, target, held, spec, info)
    try:
        path = save_critic(model, tmp_path / "copy.critic.safetensors", "0" * 64, {"spec": {}, "config": {}})
        fresh = adapt_model(tmp_path, target, held, spec, {**info, "adapt": {"critic_from": None}})
        try:
            critic_into_sb3(path, fresh)
            for name, tensor in model.policy.critic.state_dict().items():
                assert torch.equal(tensor, fresh.policy.critic.state_dict()[name])
        finally:
            fresh.get_env().close()
        data = bytearray(path.read_bytes())
        data[-1] ^= 1
        path.write_bytes(bytes(data))
        with pytest.raises(PolicyFileError, match="SHA-256"):
            critic_into_sb3(path, model)
    finally:
        model.get_env().close()


def test_a_policy_without_a_critic_is_refused_before_any_simulation(tmp_path, capsys):
    actor = default_policy_path()
    for suffix in (".safetensors", ".json"):
        shutil.copy(actor.with_suffix(suffix), tmp_path / f"lonely{suffix}")
    assert main(["adapt", "--policy", str(tmp_path / "lonely.safetensors"), "--out", str(tmp_path / "run"), *TINY]) == 2
    error = capsys.readouterr().err
    assert "no critic beside its actor" in error and "lonely.critic.safetensors" in error
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("policy", ["heuristic", "policy.onnx"])
def test_a_policy_of_a_kind_without_a_critic_is_refused(tmp_path, capsys, policy):
    assert main(["adapt", "--policy", policy, "--out", str(tmp_path / "run"), *TINY]) == 2
    assert "carry no critic" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_a_world_key_that_does_not_exist_is_refused_by_name(tmp_path, capsys):
    assert main(["adapt", "--out", str(tmp_path / "run"), *TINY, "--set", "pile.particle_mass=0.4"]) == 2
    assert "pile.particle_mass" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_a_critic_of_another_actor_is_refused(tmp_path, capsys):
    actor = default_policy_path()
    for suffix in (".safetensors", ".json"):
        shutil.copy(actor.with_suffix(suffix), tmp_path / f"other{suffix}")
        shutil.copy(critic_path_for(actor).with_suffix(suffix), tmp_path / f"other.critic{suffix}")
    meta = json.loads((tmp_path / "other.critic.json").read_text())
    (tmp_path / "other.critic.json").write_text(json.dumps({**meta, "actor_sha256": "f" * 64}))
    assert main(["adapt", "--policy", str(tmp_path / "other.safetensors"), "--out", str(tmp_path / "run"), *TINY]) == 2
    assert "trained with another actor" in capsys.readouterr().err


def test_a_shipped_actor_kept_before_its_runs_last_critic_is_accepted_by_name_only(tmp_path):
    """A run keeps a snapshot; its critic is the last actor's. Shipped beside each other, the critic's sidecar
    names the kept actor (``kept_actor_sha256``, as compact's default does); any other actor is still refused."""
    from autoscoop.training.adapt import adapt_source

    actor = default_policy_path()
    for suffix in (".safetensors", ".json"):
        shutil.copy(actor.with_suffix(suffix), tmp_path / f"kept{suffix}")
        shutil.copy(critic_path_for(actor).with_suffix(suffix), tmp_path / f"kept.critic{suffix}")
    meta = json.loads((tmp_path / "kept.critic.json").read_text())
    paired = {**meta, "actor_sha256": "f" * 64, "kept_actor_sha256": sha256_of(actor)}
    (tmp_path / "kept.critic.json").write_text(json.dumps(paired))
    assert adapt_source(str(tmp_path / "kept.safetensors")).critic == tmp_path / "kept.critic.safetensors"
    (tmp_path / "kept.critic.json").write_text(json.dumps({**paired, "kept_actor_sha256": "e" * 64}))
    with pytest.raises(PolicyFileError, match="trained with another actor"):
        adapt_source(str(tmp_path / "kept.safetensors"))


def test_a_small_adapt_run_keeps_a_validated_snapshot_and_exports_it(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["adapt", "--out", str(run), *TINY, "--set", "pile.particle_mass_kg=0.4"]) == 0
    info = json.loads((run / "run.json").read_text())
    assert info["status"] == "finished" and info["recipe"] == "adapt"
    selection = json.loads((run / "selection.json").read_text())
    assert {c["name"] for c in selection["candidates"]} <= {"start", "episode 3", "episode 6"}
    assert "start" in {c["name"] for c in selection["candidates"]}
    assert all(c["cases"] == 12 for c in selection["candidates"])  # the target world and the eleven stress cases
    assert (run / "policy.onnx").is_file() and (run / "critic.safetensors").is_file()
    assert selection["settings"]["confidence"] == 0.95
    confirmation = selection["confirmation"]  # a snapshot that ranks above the start is run again beside it
    ranked_first = selection["candidates"][0]["name"]
    assert (confirmation is None) == (ranked_first == "start")
    if confirmation is not None:
        assert confirmation["seed"] == 30_001 and confirmation["candidate"] == ranked_first
        kept_start = selection["selected_episode"] == 0
        assert confirmation["confirmed"] == (confirmation["confidence"] >= 0.95) == (not kept_start)
    # training, periodic (0, 3, 6), validation, and the confirmation's two policies
    assert info["scoops_simulated"] == 6 + 1 * 3 + 2 * 12 * 1 + (2 * 12 * 1 if confirmation else 0)
    assert "simulated scoops" in capsys.readouterr().out
    # an adapted run can be adapted again: its critic lies beside it
    critic = read_critic_sidecar(run / "critic.safetensors")
    assert critic["config"]["pile"]["particle_mass_kg"] == 0.4


def test_an_adapt_run_killed_mid_way_resumes_to_the_end(tmp_path):
    run = tmp_path / "run"
    log = tmp_path / "driver.log"
    with log.open("w") as sink:  # a file, not a pipe: the simulators' workers outlive the killed process
        killed = forked.Popen([sys.executable, "-c", KILL_DRIVER, "5", "adapt", "--out", str(run), *TINY,
                               "--checkpoint-every", "2"], stdout=sink, stderr=subprocess.STDOUT,
                              start_new_session=True)
        try:
            killed.wait(timeout=120)
        finally:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(killed.pid, signal.SIGKILL)  # its simulators' workers too
    assert killed.returncode == -signal.SIGKILL, log.read_text()[-2000:]
    assert json.loads((run / "run.json").read_text())["status"] == "running"
    assert json.loads((run / "checkpoint" / "state.json").read_text())["episodes_done"] == 4
    assert main(["adapt", "--resume", str(run), "--no-progress", "--candidates", "1", "--validation-episodes", "1",
                 "--workers", "1"]) == 0
    info = json.loads((run / "run.json").read_text())
    assert info["status"] == "finished"
    rows = (run / "episodes.csv").read_text().strip().splitlines()
    assert len(rows) == 1 + 6
    assert (run / "selection.json").is_file()


def test_resume_refuses_a_new_world(tmp_path, capsys):
    assert main(["adapt", "--resume", str(tmp_path), "--set", "pile.angle_deg=25"]) == 2
    assert "--set" in capsys.readouterr().err


def test_adapt_help_names_every_option(capsys):
    with pytest.raises(SystemExit):
        main(["adapt", "--help"])
    text = capsys.readouterr().out
    for option in ("--policy", "--set", "--config", "--episodes", "--seed", "--resume", "--held-envs",
                   "--critic-warmup-steps", "--actor-lr-scale", "--eval-episodes", "--candidates", "--validation-episodes",
                   "--confidence"):
        assert option in text



def test_the_anchored_actor_drifts_less_from_its_start_than_plain_ddpg():
    import copy

    import gymnasium as gym
    from stable_baselines3 import DDPG

    from autoscoop.agents.anchored import AnchoredDDPG

    def drift(algo_cls, alpha=None):
        model = algo_cls("MlpPolicy", gym.make("Pendulum-v1"), learning_starts=64, batch_size=64, seed=0,
                         learning_rate=3e-3, policy_kwargs={"net_arch": [32, 32]}, device="cpu")
        start = copy.deepcopy(model.actor)
        if alpha is not None:
            model.set_anchor(model.actor, alpha)
        model.learn(400)
        states = torch.as_tensor(model.replay_buffer.observations[:400, 0])
        with torch.no_grad():
            return float(((model.actor(states) - start(states)) ** 2).mean())

    plain, anchored = drift(DDPG), drift(AnchoredDDPG, alpha=0.05)
    assert anchored < 0.5 * plain, (anchored, plain)
    assert drift(AnchoredDDPG) == pytest.approx(plain)  # no anchor: DDPG unchanged
    with pytest.raises(ValueError, match="above 0"):
        AnchoredDDPG("MlpPolicy", gym.make("Pendulum-v1"), device="cpu").set_anchor(torch.nn.Linear(1, 1), 0.0)


def test_a_confirmation_of_the_start_against_itself_is_never_sure(capsys):
    """The confirmation runs both policies on the seeds after the validation's; a candidate no different from the
    start (here the same file) never confirms, so the run keeps the policy it started from."""
    from types import SimpleNamespace

    from autoscoop.commands.adapt_cmd import confirm_candidate
    from autoscoop.evaluation.stress import STRESS_THRESHOLDS, StressCase

    target = StressCase("target", "heavy earth", {"pile.particle_mass_kg": 0.4}, STRESS_THRESHOLDS)
    same = SimpleNamespace(name="episode 3", path=default_policy_path())
    record = confirm_candidate(default_policy_path(), same, target, 1, 1, True, 0.95)
    assert record["seed"] == 30_001 and record["episodes"] == 1
    assert record["confidence"] == 0.0 and not record["confirmed"]
    assert record["start"]["by_case"] == record["candidate_figures"]["by_case"]
    assert len(record["start"]["by_case"]) == 12  # the target world and the eleven stress cases
    assert "the start kept" in capsys.readouterr().out
