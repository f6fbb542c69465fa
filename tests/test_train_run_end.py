"""``train`` ends by saying what it kept: the snapshot, its episode and its validation figures; plainly so when it
kept no policy that scoops or none evaluated; and its time in one sentence."""

import json

from autoscoop.cli import main
from autoscoop.commands.train_cmd import kept_policy_lines, timing_line

FAST = ["--recipe", "paper", "--set", "pile.variants=2", "--no-progress"]
EVALUATIONS = "episode,delivered_fill,fill_factor,success,cycle_time_s\n"


def _run_dir(tmp_path, info: dict, evaluations: str = "", selection: dict | None = None):
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"episodes": 100, "eval_episodes": 10, **info}))
    (run / "evaluations.csv").write_text(EVALUATIONS + evaluations)
    if selection is not None:
        (run / "selection.json").write_text(json.dumps(selection))
    return run


def test_a_short_run_says_its_policy_was_scored_0_and_that_it_kept_none_that_scoops(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["train", "--episodes", "2", "--eval-episodes", "1", "--out", str(out), *FAST]) == 0
    printed = capsys.readouterr().out
    assert "kept policy: the snapshot of episode 2, its only periodic evaluation, at the end of training" in printed
    assert "success 0.00, no cycle time (none succeeded)" in printed
    assert "the run kept no policy that scoops: its best periodic evaluation scored 0" in printed
    assert "this session took" in printed and "command wall time" not in printed


def test_the_kept_snapshot_is_named_with_its_periodic_figures(tmp_path):
    run = _run_dir(tmp_path, {"best_score": 0.74, "best_episode": 100},
                   "50,0.2,0.4,0.3,5.1\n100,0.74,0.75,1.0,4.22\n")
    lines = kept_policy_lines(run)
    assert lines == ["kept policy: the snapshot of episode 100, the best of 2 periodic evaluations (10 episodes from "
                     "seed 10000): fill factor 0.750, success 1.00, cycle time 4.22 s (successes), delivered fill 0.740"]


def test_a_snapshot_chosen_on_the_stress_suite_is_named_with_its_validation(tmp_path):
    candidate = {"name": "episode 50", "cases_passed": 10, "cases": 11, "mean_delivered_fill": 0.7123,
                 "by_case": {"nominal": {"fill_factor_mean": 0.76, "success_rate": 1.0}}}
    run = _run_dir(tmp_path, {"best_score": 0.74, "best_episode": 100, "selected_episode": 50},
                   "50,0.7,0.71,1.0,4.5\n100,0.74,0.75,1.0,4.22\n",
                   {"settings": {"episodes": 20, "seed": 5000}, "selected_episode": 50, "candidates": [candidate]})
    assert kept_policy_lines(run) == [
        "kept policy: the snapshot of episode 50, chosen on the stress suite (20 episodes a case from seed 5000): "
        "10 of 11 cases hold, mean delivered fill 0.712; nominal: fill factor 0.760, success 1.00"]


def test_a_run_without_evaluations_says_it_kept_none_evaluated(tmp_path):
    (line,) = kept_policy_lines(_run_dir(tmp_path, {"eval_every": 0}))
    assert line.startswith("kept policy: none evaluated; no periodic evaluation ran")


def test_the_time_reads_as_one_sentence_new_and_resumed():
    assert timing_line(62.4, 55.0, resumed=False) == "this session took 62 s, of which training took 55 s"
    assert timing_line(62.4, 78.2, resumed=True) == (
        "this session took 62 s; the run's training time so far is 78 s (this session and the earlier ones together)")
    assert timing_line(2.94, 0.2, resumed=False) == "this session took 2.9 s, of which training took 0.2 s"
