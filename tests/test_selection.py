"""Choosing the kept policy among a run's snapshots on a validation suite (a recipe's ``selection``)."""

import json
import math
import shutil
from dataclasses import replace

import pytest

from autoscoop.agents.critic_files import read_critic_sidecar
from autoscoop.agents.policy_files import sha256_of
from autoscoop.cli import main
from autoscoop.envs.outcome import EpisodeOutcome
from autoscoop.evaluation.selection import delivered_fill, threshold_shortfall, total_shortfall
from autoscoop.evaluation.stress import CASES, StressRow
from autoscoop.training.adapt import adapt_source
from autoscoop.training.checkpoints import keep_snapshot, snapshot_candidates
from autoscoop.training.settings import selection_settings


def row(case_name: str, **stats: float) -> StressRow:
    case = next(c for c in CASES if c.name == case_name)
    base = {"fill_factor_mean": 0.8, "volumetric_fill_mean": 0.7, "success_rate": 1.0, "overload_rate": 0.0,
            "cycle_time_mean": 4.5}
    return StressRow(case, {**base, **stats})


def test_shortfall_adds_the_missing_margins_and_is_zero_when_every_threshold_holds():
    assert threshold_shortfall(row("heavy")) == 0.0
    assert threshold_shortfall(row("nominal")) == 0.0
    # success 0.85 (0.05 short), overload 0.15 (0.10 over): 0.15
    assert threshold_shortfall(row("heavy", success_rate=0.85, overload_rate=0.15)) == pytest.approx(0.15)
    # nominal: fill 0.70 (0.05 short) and a cycle of 6 s (1 s over, a fifth of a unit)
    assert threshold_shortfall(row("nominal", fill_factor_mean=0.70, cycle_time_mean=6.0)) == pytest.approx(0.25)
    # no successful episode: the cycle time is NaN and counts as one whole unit
    assert threshold_shortfall(row("nominal", success_rate=0.0, cycle_time_mean=math.nan)) == pytest.approx(0.97 + 1.0)
    rows = [row("heavy", success_rate=0.85), row("light", volumetric_fill_mean=0.5), row("angle_40")]
    assert total_shortfall(rows) == pytest.approx(0.15)


def test_delivered_fill_counts_failures_as_empty_and_caps_an_overload():
    def outcome(fill: float, success: bool) -> EpisodeOutcome:
        return EpisodeOutcome(seed=0, fill_factor=fill, mass_kg=fill * 7, particles=0, success=success,
                              cycle_time_s=4.0 if success else None, spilled=0, physics_error=False, steps=16,
                              episode_return=0.0)

    stress_row = StressRow(CASES[0], {}, [outcome(0.8, True), outcome(1.2, True), outcome(0.9, False)])
    assert delivered_fill(stress_row) == pytest.approx((0.8 + 1.0 + 0.0) / 3)


def test_selection_settings_are_checked():
    assert selection_settings({}) is None
    settings = selection_settings({"selection": {"candidates": 3, "episodes": 5, "seed": 20000}})
    assert (settings.candidates, settings.episodes, settings.seed) == (3, 5, 20000)
    with pytest.raises(ValueError, match="selection.episodes"):
        selection_settings({"selection": {"candidates": 3, "episodes": 0, "seed": 1}})
    with pytest.raises(ValueError, match="selection.seed"):
        selection_settings({"selection": {"candidates": 3, "episodes": 2}})


def test_candidates_are_the_best_snapshots_of_the_last_world_and_keeping_one_makes_it_the_policy(tmp_path):
    run = tmp_path / "run"
    (run / "evaluated").mkdir(parents=True)
    rows = [(50, 0.9), (100, 0.2), (150, 0.6), (200, 0.6), (250, 0.1), (300, 0.5)]
    (run / "evaluations.csv").write_text("episode,delivered_fill,fill_factor,success,cycle_time_s\n" + "".join(
        f"{episode},{score},{score},1.0,4.0\n" for episode, score in rows))
    for episode, _ in rows:
        if episode != 300:  # a snapshot whose actor file is missing is skipped
            (run / "evaluated" / f"episode_{episode:05d}.safetensors").write_bytes(b"w%d" % episode)
            (run / "evaluated" / f"episode_{episode:05d}.json").write_text(json.dumps({"episode": episode}))
    (run / "run.json").write_text(json.dumps({"status": "finished", "best_episode": 50}))
    found = snapshot_candidates(run, count=3, after_episode=100)
    assert [(episode, score) for episode, score, _ in found] == [(200, 0.6), (150, 0.6), (250, 0.1)]
    keep_snapshot(run, 150, {"selected_episode": 150})
    assert (run / "policy.safetensors").read_bytes() == b"w150"
    assert json.loads((run / "policy.json").read_text()) == {"episode": 150}
    assert json.loads((run / "run.json").read_text())["selected_episode"] == 150
    assert json.loads((run / "selection.json").read_text()) == {"selected_episode": 150}


def test_a_recipe_with_selection_validates_its_snapshots_and_a_resume_finishes_the_choice(tmp_path, monkeypatch):
    """The train command runs the recipe's selection after training; a run killed during it (finished, no
    selection.json) gets it from ``--resume``, with the same choice."""
    from autoscoop.training import run as train_mod
    from autoscoop.training import settings

    original = settings.load_recipe
    monkeypatch.setattr(train_mod, "load_recipe", lambda algo, recipe: {
        **original(algo, "paper"), "selection": {"candidates": 2, "episodes": 1, "seed": 20000}})
    out = tmp_path / "run"
    assert main(["train", "--episodes", "4", "--eval-every", "2", "--eval-episodes", "1", "--out", str(out),
                 "--set", "pile.variants=2", "--no-progress"]) == 0
    record = json.loads((out / "selection.json").read_text())
    assert record["settings"] == {"candidates": 2, "episodes": 1, "seed": 20000, "after_episode": 0}
    assert record["wall_s"] > 0
    assert sorted(c["name"] for c in record["candidates"]) == ["episode 2", "episode 4"]
    assert all(c["cases"] == len(CASES) for c in record["candidates"])
    shortfalls = [c["shortfall"] for c in record["candidates"]]
    assert shortfalls == sorted(shortfalls)  # best first
    chosen = record["selected_episode"]
    assert record["candidates"][0]["name"] == f"episode {chosen}"
    assert json.loads((out / "run.json").read_text())["selected_episode"] == chosen
    snapshot = out / "evaluated" / f"episode_{chosen:05d}.safetensors"
    assert (out / "policy.safetensors").read_bytes() == snapshot.read_bytes()
    # the critic (its run's last actor's) names the kept actor: the pair adapts from a copy of the two files
    assert read_critic_sidecar(out / "critic.safetensors")["kept_actor_sha256"] == sha256_of(snapshot)
    shutil.copyfile(snapshot, tmp_path / "kept.safetensors")
    shutil.copyfile(snapshot.with_suffix(".json"), tmp_path / "kept.json")
    shutil.copyfile(out / "critic.safetensors", tmp_path / "kept.critic.safetensors")
    shutil.copyfile(out / "critic.json", tmp_path / "kept.critic.json")
    assert adapt_source(str(tmp_path / "kept.safetensors")).actor == tmp_path / "kept.safetensors"

    (out / "selection.json").unlink()  # as if killed while validating
    (out / "policy.safetensors").write_bytes(b"stale")
    assert main(["train", "--resume", str(out), "--no-progress"]) == 0
    assert json.loads((out / "selection.json").read_text())["selected_episode"] == chosen
    assert (out / "policy.safetensors").read_bytes() == snapshot.read_bytes()
    assert main(["train", "--resume", str(out), "--no-progress"]) == 2  # now finished and chosen: nothing to do


def test_ground_lost_counts_beyond_the_tolerance_where_the_start_held_and_weighs_as_a_shortfall_does():
    from autoscoop.evaluation.selection import RankedForTarget, regression_from

    start = [row("heavy", success_rate=0.80), row("light"), row("angle_25", volumetric_fill_mean=0.69)]
    # heavy: the start fails it, so no ground there; light: 0.02 lower, within the 0.03; angle_25: 0.05 lower
    tuned = [row("heavy", success_rate=0.70), row("light", volumetric_fill_mean=0.68),
             row("angle_25", volumetric_fill_mean=0.64)]
    assert regression_from(start, start) == 0.0
    assert regression_from(tuned, start) == pytest.approx(0.02)
    # a start that fails its target world by 0.45 in success ranks below a candidate that passes it and lost
    # 0.02 of fill in one case: the two are in one unit
    target = next(c for c in CASES if c.name == "light")
    kept = RankedForTarget("episode 275", None, [StressRow(target, row("light").stats), *tuned],
                           regression=regression_from(tuned, start))
    stayed = RankedForTarget("start", None, [StressRow(target, row("light", success_rate=0.45).stats), *start])
    assert kept.score < stayed.score


def _episodes(case_name: str, successes: list[bool], fill: float = 0.8) -> StressRow:
    """A case's row from episodes on seeds 0.. with these successes (fill factor ``fill``, volumetric 0.7)."""
    from autoscoop.evaluation.stress import row_from_outcomes

    case = next(c for c in CASES if c.name == case_name)
    return row_from_outcomes(case, [EpisodeOutcome(seed=i, fill_factor=fill, mass_kg=fill * 7, particles=20,
                                                   success=ok, cycle_time_s=4.0 if ok else None, spilled=0,
                                                   physics_error=False, steps=80, episode_return=0.0,
                                                   volumetric_fill=0.7)
                                    for i, ok in enumerate(successes)])


def test_a_confirmation_is_sure_of_a_clear_gain_and_not_of_none_or_of_noise():
    from autoscoop.evaluation.selection import confidence_of_gain

    held = _episodes("angle_40", [True] * 20)
    start = [_episodes("heavy", [True] * 10 + [False] * 10), held]
    # fails the target world on half its piles where the candidate fails on none: sure
    assert confidence_of_gain(start, [_episodes("heavy", [True] * 20), held]) > 0.99
    # the same episodes: never better
    assert confidence_of_gain(start, start) == 0.0
    # one pile more of twenty, as noise gives: far from sure
    noisy_start = [_episodes("heavy", [True] * 17 + [False] * 3), held]
    assert confidence_of_gain(noisy_start, [_episodes("heavy", [True] * 18 + [False] * 2), held]) < 0.5
    # a gain in the target world paid for in a case the start held (success 1.0 -> 0.8) is no gain
    lost = _episodes("angle_40", [True] * 16 + [False] * 4)
    assert confidence_of_gain(start, [_episodes("heavy", [True] * 12 + [False] * 8), lost]) < 0.5


def test_a_confirmation_compares_the_same_piles_only():
    from autoscoop.evaluation.selection import confidence_of_gain

    start = [_episodes("heavy", [True] * 4)]
    other_seeds = StressRow(start[0].case, start[0].stats, [replace(o, seed=o.seed + 1) for o in start[0].outcomes])
    with pytest.raises(ValueError, match="same seeds"):
        confidence_of_gain(start, [other_seeds])
    with pytest.raises(ValueError, match="same cases"):
        confidence_of_gain(start, [_episodes("light", [True] * 4)])


def test_a_draw_computes_the_statistics_as_the_stress_suite_does():
    """The bootstrap's statistics (vectorised over draws) are outcome_statistics' own: every episode once, in order,
    gives the same figures, a case with no success (cycle time NaN) and no volumetric fill (NaN) included."""
    import numpy as np

    from autoscoop.evaluation.selection import DRAWN_METRICS, _drawn_statistics
    from autoscoop.evaluation.summary import outcome_statistics

    mixed = _episodes("heavy", [True, False, True, True, False], fill=0.9).outcomes
    mixed = [replace(o, overloaded=i == 2, fill_factor=0.7 + 0.1 * i) for i, o in enumerate(mixed)]
    empty = [replace(o, volumetric_fill=math.nan) for o in _episodes("light", [False] * 3).outcomes]
    for outcomes in (mixed, empty):
        drawn = _drawn_statistics(outcomes, np.arange(len(outcomes))[None, :])[0]
        expected = outcome_statistics(o.as_dict() for o in outcomes)
        for metric in DRAWN_METRICS:
            assert drawn[metric] == pytest.approx(expected[metric], nan_ok=True), metric
