"""The training log and the learning curve follow the definition: cycle time is seconds from the start until
success; an episode that did not succeed (timed out, or reached the terminal point with too little in the bucket)
has none, and is counted apart."""

import csv
import math
from types import SimpleNamespace

import numpy as np

from autoscoop.training.callbacks import EpisodeLogger
from autoscoop.training.learning_curve import plot_learning_curve, read_episodes


class Scalars:
    """A stand-in for SB3's logger: the scalars recorded, by key."""

    def __init__(self) -> None:
        self.recorded: dict[str, list[float]] = {}

    def record(self, key: str, value: float) -> None:
        self.recorded.setdefault(key, []).append(value)


def _info(success: bool, reached: bool, elapsed_s: float) -> dict:
    info = {"fill_factor": 0.7 if success else 0.3, "success": success, "reached": reached, "elapsed_s": elapsed_s,
            "spilled": 0, "physics_error": False}
    if reached:  # the environment times the arrival, loaded or not
        info["cycle_time_s"] = elapsed_s
    return info


def test_a_failed_episode_is_logged_without_a_cycle_time(tmp_path):
    logger = EpisodeLogger(tmp_path, episodes=10, done=0, info={}, spec={}, checkpoint_every=100, progress=False)
    scalars = Scalars()
    logger.model = SimpleNamespace(logger=scalars)
    logger.end_episode(0, _info(success=True, reached=True, elapsed_s=4.25))
    logger.end_episode(0, _info(success=False, reached=True, elapsed_s=5.0))  # arrived with too little
    logger.end_episode(0, _info(success=False, reached=False, elapsed_s=8.0))  # timed out
    logger.csv_file.close()
    with open(tmp_path / "episodes.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [row["success"] for row in rows] == ["1", "0", "0"]
    assert float(rows[0]["cycle_time_s"]) == 4.25
    assert all(math.isnan(float(row["cycle_time_s"])) for row in rows[1:])
    assert scalars.recorded["scoop/cycle_time_s"] == [4.25]  # TensorBoard: successes only
    assert scalars.recorded["scoop/success"] == [1, 0, 0]


def test_the_learning_curve_draws_no_cycle_time_for_a_failed_episode_of_an_older_log(tmp_path):
    log = tmp_path / "episodes.csv"
    log.write_text("episode,reward,fill_factor,cycle_time_s,success,steps,spilled,physics_error,wall_s\n"
                   "1,10.0,0.7,4.25,1,17,0,0,1.0\n"
                   "2,8.0,0.3,5.0,0,20,0,0,2.0\n"  # a cycle time an older log gave a failed episode
                   "3,6.0,0.1,nan,0,32,0,0,3.0\n")
    columns = read_episodes(log)
    assert columns["cycle_time_s"][0] == 4.25 and np.isnan(columns["cycle_time_s"][1:]).all()
    assert plot_learning_curve(log, tmp_path / "curve.png").stat().st_size > 1000
