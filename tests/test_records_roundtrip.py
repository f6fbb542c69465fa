"""Episode records: what an episode writes is what loads back; evaluation saves one per episode."""

import numpy as np
import pytest

from autoscoop.agents.loading import heuristic_for
from autoscoop.core.config import ScoopConfig
from autoscoop.envs.records import STEP_FIELDS, load_record
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.evaluation.evaluate import evaluate
from autoscoop.evaluation.recorder import EpisodeRecorder, record_name

SHORT = ScoopConfig().with_overrides({"env.max_episode_s": 1.5, "pile.variants": 1})


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    env = EpisodeRecorder(make_scoop_env(SHORT), {"policy": "heuristic", "source": "test"})
    result = rollout(heuristic_for(SHORT), env, seed=3)
    path = env.save(tmp_path_factory.mktemp("records") / "one.npz")
    return env.record, result, path


def test_a_record_round_trips(recorded):
    record, result, path = recorded
    loaded = load_record(path)
    assert len(loaded) == len(record) == result.steps == SHORT.max_episode_steps
    before, after = record.arrays(), loaded.arrays()
    assert set(after) == set(STEP_FIELDS)
    for name in STEP_FIELDS:
        np.testing.assert_array_equal(after[name], before[name], err_msg=name)
    assert after["state"].shape == (len(record), 12)
    assert after["action"].shape == (len(record), 3)
    assert after["tip_world_m"].shape == (len(record), 3)
    assert loaded.meta == record.meta


def test_a_record_holds_the_outcome_and_the_start(recorded):
    record, result, _ = recorded
    meta = record.meta
    assert meta["seed"] == 3 and meta["policy"] == "heuristic" and meta["source"] == "test"
    assert meta["pile"]["angle_deg"] == SHORT.pile.angle_deg and meta["time_limit_s"] == 1.5
    outcome = meta["outcome"]
    assert outcome["particles"] == result.particles and outcome["steps"] == result.steps
    assert outcome["mass_kg"] == pytest.approx(result.mass_kg)
    assert outcome["episode_return"] == pytest.approx(result.episode_return)
    assert len(meta["start"]["particles_xz_m"]) == SHORT.pile.n_particles
    arrays = record.arrays()
    np.testing.assert_allclose(arrays["reward_progress"] + arrays["reward_mass"], arrays["reward"])
    np.testing.assert_allclose(arrays["time_s"], SHORT.env.control_period_s * np.arange(1, len(record) + 1))


def test_evaluate_saves_one_record_per_episode(tmp_path):
    results = evaluate(heuristic_for(SHORT), SHORT, episodes=2, seed=5, progress=False, records_dir=tmp_path,
                       records_meta={"policy": "heuristic"})
    for result in results:
        record = load_record(tmp_path / record_name(result.seed))
        assert record.meta["seed"] == result.seed and record.meta["source"] == "eval"
        assert record.meta["outcome"]["fill_factor"] == pytest.approx(result.fill_factor)
        assert record.meta["outcome"]["success"] == result.success
        assert len(record) == result.steps


def test_loading_something_else_fails_clearly(tmp_path):
    path = tmp_path / "other.npz"
    np.savez(path, x=np.zeros(3))
    with pytest.raises(ValueError, match="not an autoscoop episode record"):
        load_record(path)


def test_a_record_names_the_pile_the_episode_had_in_a_mix():
    config = ScoopConfig().with_overrides({"pile.angle_mix_deg": [25, 40], "pile.variants": 2})
    env = EpisodeRecorder(make_scoop_env(config), {"policy": "test"})
    angles = set()
    for seed in range(6):
        env.reset(seed=seed)
        angle = env.record.meta["pile"]["angle_deg"]
        assert angle == env.unwrapped.sim.pile_angle_deg
        angles.add(angle)
    assert angles == {25.0, 40.0}
    env.close()


def test_a_broken_record_is_a_clear_error_naming_the_file(tmp_path) -> None:
    """Truncated, garbage, pickled or missing records: a ValueError naming the file, never a raw traceback."""
    import zipfile

    import numpy as np
    import pytest

    from autoscoop.envs.records import EpisodeRecord, load_record

    good = EpisodeRecord(meta={"seed": 0}).save(tmp_path / "good.npz")
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(good.read_bytes()[: len(good.read_bytes()) // 2])
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a zip at all" * 10)
    pickled = tmp_path / "pickled.npz"
    np.savez(pickled, meta=np.array([{"a": 1}], dtype=object))
    for path in (truncated, garbage, pickled, tmp_path / "missing.npz"):
        with pytest.raises(ValueError, match=path.name) as caught:
            load_record(path)
        assert not isinstance(caught.value, zipfile.BadZipFile)
