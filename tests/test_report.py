"""Reports are drawn from records alone: phases, the Table 2 numbers, the figures, ``autoscoop report``."""

import numpy as np
import pytest

from autoscoop.agents.loading import heuristic_for
from autoscoop.cli import main
from autoscoop.core.config import ScoopConfig
from autoscoop.core.phases import phase_now, phase_spans
from autoscoop.envs.definitions import definition_lines
from autoscoop.evaluation.evaluate import evaluate, summarize
from autoscoop.report.data import group_episodes, load_episodes, summarize_episodes
from autoscoop.report.figures import plot_bucket_torque, plot_by_angle, plot_cycle
from autoscoop.report.markdown import REPORT_TERMS, results_table, write_report

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def is_png(path) -> bool:
    return path.is_file() and path.read_bytes()[:8] == PNG_SIGNATURE and path.stat().st_size > 10_000


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """Two full heuristic scoops on the 32 deg pile and one each on 25 and 40 deg."""
    root = tmp_path_factory.mktemp("records")
    results = {}
    for angle, episodes in ((32.0, 2), (25.0, 1), (40.0, 1)):
        config = ScoopConfig().with_overrides({"pile.angle_deg": angle, "pile.variants": 1})
        results[angle] = (config, evaluate(heuristic_for(config), config, episodes, progress=False,
                                           records_dir=root / f"{angle:g}", records_meta={"policy": "heuristic"}))
    return root, results


def test_phases_split_at_first_and_last_penetration():
    spans = phase_spans(np.array([0, 0, 1, 1, 0, 1, 0, 0]), 0.25 * np.arange(1, 9))
    assert spans.steps == {"approach": (0, 2), "fill": (2, 6), "exit": (6, 8)}
    assert spans.times_s == {"approach": (0.0, 0.5), "fill": (0.5, 1.5), "exit": (1.5, 2.0)}
    assert [spans.at_step(i) for i in (0, 2, 4, 7)] == ["approach", "fill", "fill", "exit"]
    never = phase_spans(np.zeros(4), 0.25 * np.arange(1, 5))
    assert never.steps["approach"] == (0, 4) and never.steps["fill"] == (4, 4)
    assert [phase_now(False, False), phase_now(False, True), phase_now(True, False)] == ["approach", "fill", "exit"]


def test_the_table_from_records_matches_evaluation(records):
    root, results = records
    config, evaluated = results[32.0]
    episodes = load_episodes([root / "32"])
    mine = summarize_episodes(episodes)
    theirs = summarize(evaluated, config, "heuristic")
    for key in ("fill_factor_mean", "fill_factor_std", "mass_kg_mean", "mass_kg_std", "cycle_time_mean",
                "spillage_mean", "success_rate"):
        assert mine[key] == pytest.approx(theirs[key], nan_ok=True), key
    table = results_table(group_episodes(episodes))
    assert "| heuristic | 32° | 2 |" in table and "paper: DRL controller" in table


def test_figures_are_drawn_from_records(records, tmp_path):
    root, _ = records
    episodes = load_episodes([root])
    first = [e for e in episodes if e.angle_deg == 32.0]
    assert is_png(plot_cycle(first[0], tmp_path / "cycle.png"))
    assert is_png(plot_bucket_torque(first, tmp_path / "torque.png"))
    assert is_png(plot_by_angle(group_episodes(episodes), tmp_path / "angles.png"))
    phases = first[0].phases()
    assert phases.steps["fill"][1] > phases.steps["fill"][0], "a heuristic scoop penetrates the pile"


def test_report_command_redraws_without_simulating(records, tmp_path, monkeypatch, capsys):
    root, _ = records
    import autoscoop.sim.scene as scene

    def no_simulator(*args, **kwargs):
        raise AssertionError("the report must not build a simulator")

    monkeypatch.setattr(scene.ScoopSim, "__init__", no_simulator)
    assert main(["report", str(root), "--out", str(tmp_path)]) == 0
    text = (tmp_path / "report.md").read_text()
    assert "## Results (paper Table 2)" in text and "| heuristic | 40° | 1 |" in text
    for line in definition_lines(REPORT_TERMS):  # success is reached loaded, as the code counts it
        assert line in text
    for name in ("fig13_tip_by_angle.png", "fig9_cycle.png", "fig11_bucket_torque.png"):
        assert f"]({name})" in text and is_png(tmp_path / name)
    assert "wrote" in capsys.readouterr().out


def test_report_of_nothing_is_a_clear_error(tmp_path, capsys):
    assert main(["report", str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    assert "no episode records" in capsys.readouterr().err


def test_write_report_names_each_controller_figure(records, tmp_path):
    root, _ = records
    episodes = load_episodes([root])
    for episode in episodes[:1]:
        episode.record.meta["policy"] = "runs/best/policy.safetensors"
    files = write_report(episodes, tmp_path)
    names = sorted(p.name for p in files.figures)
    assert "fig9_cycle_policy.png" in names and "fig9_cycle_heuristic.png" in names
