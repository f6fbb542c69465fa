"""Manual control: the key map turns key presses into actions; a session records episodes (no display)."""

import contextlib

import numpy as np
import pytest

from autoscoop.core.config import ScoopConfig
from autoscoop.core.state import CommandLimits
from autoscoop.envs.records import load_record
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.evaluation.recorder import EpisodeRecorder
from autoscoop.evaluation.teleop import (
    BINDINGS,
    KEY_DOWN,
    KEY_ENTER,
    KEY_KP_8,
    KEY_LEFT,
    KEY_PAGE_DOWN,
    KEY_PAGE_UP,
    KEY_RIGHT,
    KEY_SPACE,
    KEY_UP,
    SessionOptions,
    TeleopKeys,
    TeleopSteps,
    help_lines,
    run_session,
)

LIMITS = CommandLimits()
SPAN = LIMITS.high - LIMITS.low  # 0.2 m/s, 0.42 rad, 1.4 rad
START = np.array([0.0, 0.23, 0.0])


def keys_at_start() -> TeleopKeys:
    keys = TeleopKeys(LIMITS, TeleopSteps(speed_mps=0.025, lift_rad=0.04, tilt_rad=0.10))
    keys.reset(START)
    return keys


def test_no_key_no_action():
    keys = keys_at_start()
    np.testing.assert_array_equal(keys.next_action(), np.zeros(3))


@pytest.mark.parametrize("key, index, change", [
    (KEY_UP, 0, 0.025), (KEY_DOWN, 0, -0.025), (KEY_PAGE_UP, 1, -0.04), (KEY_PAGE_DOWN, 1, 0.04),
    (KEY_LEFT, 2, -0.10), (KEY_RIGHT, 2, 0.10), (KEY_KP_8, 0, 0.025),
])
def test_each_key_moves_one_target_by_one_step(key, index, change):
    keys = keys_at_start()
    assert keys.press(key) is not None
    expected = np.zeros(3)
    expected[index] = change / SPAN[index]
    np.testing.assert_allclose(keys.next_action(), expected, atol=1e-6)
    np.testing.assert_allclose(keys.next_action(), np.zeros(3), atol=1e-6)  # reached: nothing more to do


def test_speed_is_held_until_space_stops_it():
    keys = keys_at_start()
    keys.press(KEY_UP)
    keys.press(KEY_UP)
    np.testing.assert_allclose(keys.next_action(), [0.05 / 0.2, 0, 0], atol=1e-6)
    assert keys.asked[0] == pytest.approx(0.05)
    keys.press(KEY_SPACE)
    np.testing.assert_allclose(keys.next_action(), [-0.05 / 0.2, 0, 0], atol=1e-6)
    assert keys.asked[0] == 0.0


def test_asks_stay_within_the_limits():
    keys = keys_at_start()
    for _ in range(20):
        keys.press(KEY_UP)
        keys.press(KEY_PAGE_UP)
        keys.press(KEY_RIGHT)
    np.testing.assert_allclose(keys.asked, [LIMITS.high[0], LIMITS.low[1], LIMITS.high[2]])
    action = keys.next_action()
    assert np.all(np.abs(action) <= 1.0)
    np.testing.assert_allclose(action, ([0.1, -0.10, 0.90] - START) / SPAN, atol=1e-6)


def test_other_keys_do_nothing_and_enter_is_remembered_once():
    keys = keys_at_start()
    assert keys.press(ord("W")) is None and keys.press(0) is None
    np.testing.assert_array_equal(keys.next_action(), np.zeros(3))
    assert keys.press(KEY_ENTER) == "enter"
    assert keys.take_enter() and not keys.take_enter()


def test_every_binding_is_documented_for_the_screen():
    assert len(help_lines()) == len(BINDINGS)
    all_keys = [k for keys, _, _ in BINDINGS.values() for k in keys]
    assert len(all_keys) == len(set(all_keys)), "one key, one command"


class FakeViewer:
    """Stands in for mujoco.viewer's window: presses scripted keys at given refreshes."""

    def __init__(self, keys: TeleopKeys, script: dict[int, list[int]], close_after: int = 10_000):
        self.keys, self.script, self.close_after = keys, script, close_after
        self.syncs, self.texts = 0, []

    def is_running(self) -> bool:
        return self.syncs < self.close_after

    def sync(self) -> None:
        for key in self.script.get(self.syncs, []):
            self.keys.press(key)
        self.syncs += 1

    def lock(self):
        return contextlib.nullcontext()

    def set_texts(self, texts) -> None:
        self.texts = texts


def test_a_session_records_the_episode_it_was_driven_through(tmp_path):
    config = ScoopConfig().with_overrides({"env.max_episode_s": 1.0, "pile.variants": 1})
    env = EpisodeRecorder(make_scoop_env(config), {"policy": "manual", "source": "teleop"})
    keys = TeleopKeys(CommandLimits.for_robot(config.robot))
    viewer = FakeViewer(keys, {0: [KEY_UP, KEY_UP, KEY_UP, KEY_UP], 3: [KEY_PAGE_UP]})
    messages = []
    saved = run_session(env, keys, viewer, SessionOptions(out_dir=tmp_path, episodes=1, speed=4.0),
                        sleep=lambda s: None, echo=messages.append)
    assert len(saved) == 1 and saved[0].parent == tmp_path
    record = load_record(saved[0])
    assert record.meta["source"] == "teleop" and record.meta["policy"] == "manual"
    assert record.meta["ended"] == "time limit" and len(record) == 4
    actions = record.arrays()["action"]
    np.testing.assert_allclose(actions[0], [0.5, 0.0, 0.0], atol=1e-6)  # four presses: full speed asked
    assert actions[1, 1] < 0  # Page Up during the first control step raises the arm next step
    assert record.arrays()["state"][-1, 6] > 0.05, "the loader drove forward"
    assert viewer.texts and "Up" in viewer.texts[0][2]
    assert "saved" in messages[0]


def test_a_second_session_into_the_same_folder_is_refused(tmp_path, monkeypatch, capsys):
    from filelock import FileLock

    from autoscoop.cli import main as cli_main
    from autoscoop.commands import RECORDS_LOCK
    from autoscoop.sim import glbackend

    monkeypatch.setattr(glbackend, "has_display", lambda environ: True)  # past the display check, to the folder
    folder = tmp_path / "manual"
    folder.mkdir()
    lock = FileLock(folder / RECORDS_LOCK)
    lock.acquire()  # another session recording there
    try:
        code = cli_main(["teleop", "--out", str(folder)])
    finally:
        lock.release()
    error = capsys.readouterr().err
    assert code == 2 and "another autoscoop process" in error and str(folder) in error
    assert [p.name for p in folder.iterdir()] == [RECORDS_LOCK]  # the viewer never opened, nothing recorded
