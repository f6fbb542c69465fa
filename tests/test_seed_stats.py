"""Seed statistics: the interquartile mean, its stratified bootstrap interval, the per-case reliability table and
``release/seed_table.py --adapt`` on an adapt benchmark's summary."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from autoscoop.report.seed_stats import bootstrap_interval, interquartile_mean, seed_reliability

ROOT = Path(__file__).resolve().parents[1]


@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=40), st.randoms())
@settings(max_examples=60, deadline=None)
def test_the_interquartile_mean_ignores_order_and_the_extreme_quarters(values, random):
    iqm = interquartile_mean(values)
    shuffled = list(values)
    random.shuffle(shuffled)
    assert interquartile_mean(shuffled) == pytest.approx(iqm, abs=1e-12)
    assert min(values) - 1e-12 <= iqm <= max(values) + 1e-12
    if len(values) < 4:  # nothing to trim
        assert iqm == pytest.approx(float(np.mean(values)), abs=1e-12)
    else:  # the highest and lowest seeds can be anything: an outlier does not move it
        extreme = sorted(values)
        extreme[-1], extreme[0] = 1e6, -1e6
        assert interquartile_mean(extreme) == pytest.approx(iqm, abs=1e-9)


def test_the_interquartile_mean_drops_one_lucky_seed_of_five():
    assert interquartile_mean([0.9, 0.91, 0.92, 0.93, 0.0]) == pytest.approx((0.9 + 0.91 + 0.92) / 3)
    with pytest.raises(ValueError, match="finite"):
        interquartile_mean([0.5, float("nan")])
    with pytest.raises(ValueError, match="finite"):
        interquartile_mean([])


def test_the_bootstrap_interval_holds_the_iqm_repeats_and_narrows_with_agreement():
    spread = [0.7, 0.8, 0.9, 0.95, 1.0]
    low, high = bootstrap_interval([spread], seed=3)
    assert low <= interquartile_mean(spread) <= high and low < high
    assert bootstrap_interval([spread], seed=3) == (low, high)
    assert bootstrap_interval([[0.9] * 5]) == pytest.approx((0.9, 0.9))
    with pytest.raises(ValueError, match="confidence"):
        bootstrap_interval([spread], confidence=1.0)
    with pytest.raises(ValueError, match="at least one run"):
        bootstrap_interval([[]])


def _case(success, fill, passed):
    return {"success_rate": success, "volumetric_fill_mean": fill, "passed": passed}


def test_seed_reliability_reports_the_share_of_seeds_holding_each_case():
    by_seed = [{"target": _case(0.95, 0.65, True), "nominal": _case(1.0, 0.7, True)},
               {"target": _case(0.80, 0.55, False), "nominal": _case(1.0, 0.7, True)}]
    table = seed_reliability(by_seed, reps=200)
    assert list(table) == ["target", "nominal"]
    assert table["target"]["share_passed"] == 0.5 and table["nominal"]["share_passed"] == 1.0
    assert table["target"]["success_rate"]["iqm"] == pytest.approx(0.875)
    assert table["nominal"]["volumetric_fill_mean"] == pytest.approx({"iqm": 0.7, "low": 0.7, "high": 0.7})
    with pytest.raises(ValueError, match="same cases"):
        seed_reliability([by_seed[0], {"target": _case(1, 1, True)}])


def test_seed_table_prints_an_adapt_summarys_reliability_table(tmp_path):
    rng = np.random.default_rng(0)
    runs = [{"world": "heavy", "seed": seed, "passed": seed != 2, "adapt_wall_s": 100.0, "scoops_simulated": 1530,
             "by_case": {"target_heavy": _case(float(rng.uniform(0.85, 1)), 0.66, seed != 2),
                         "nominal": _case(1.0, 0.70, True)}} for seed in range(5)]
    summary = tmp_path / "adapt.json"
    summary.write_text(json.dumps({"runs": runs}))
    out = tmp_path / "table.json"
    done = subprocess.run([sys.executable, str(ROOT / "release" / "seed_table.py"), "--adapt", str(summary),
                           "--json", str(out)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "**heavy** (seeds 0, 1, 2, 3, 4; 4 of 5 pass)" in done.stdout
    assert "| target_heavy |" in done.stdout and "| 80% |" in done.stdout
    written = json.loads(out.read_text())["worlds"]["heavy"]
    assert written["seeds_passing"] == 4 and written["cases"]["nominal"]["share_passed"] == 1.0
