"""A loader's shift: the scripted phases, the particle accounting, the hopper's count, a short shift, bad input."""

from __future__ import annotations

import json
import os

import mujoco
import numpy as np
import pytest

from autoscoop.agents.heuristic import HeuristicScooper
from autoscoop.cli import main
from autoscoop.core.config import ConfigError, ScoopConfig
from autoscoop.core.shift_accounting import account, pile_profile, toe_x_m, touching_cluster
from autoscoop.core.shift_checks import check_shift_config
from autoscoop.core.shift_script import PHASES, CarryDumpScript, Ranges, ScriptParams
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.envs.shift import shift_world_config
from autoscoop.evaluation.shift import run_shift
from autoscoop.sim.glbackend import has_display
from autoscoop.sim.scene import WHEELS, ScoopSim
from autoscoop.sim.shift_sim import HELD_DAMPING_NS_M, REACH_BEHIND_TOE_M, ShiftSim
from autoscoop.sim.work_meter import ACTUATORS, WorkMeter

RADIUS = 0.034
SMALL_SHIFT = {"shift.pile_particles": 72, "shift.pile_layers": 3, "pile.variants": 1}


def state(speed: float = 0.0, lift: float = 0.23, tilt: float = 0.0, tip_x: float = 1.1) -> np.ndarray:
    """A 12-number state with the readings the script uses (tip x, speed, lift, tilt)."""
    s = np.zeros(12, dtype=np.float32)
    s[1], s[6], s[7], s[8] = tip_x, speed, lift, tilt
    return s


def params(**changes) -> ScriptParams:
    base = dict(hopper_half_length_m=0.25, start_gap_m=0.1, start_lift_rad=0.23, start_tilt_rad=0.0,
                phase_limit_s=20.0)
    return ScriptParams(**{**base, **changes})


# ------------------------------------------------------------------ the scripted phases
def test_back_out_drives_back_with_the_arm_up_until_the_front_is_clear_and_the_arm_up():
    script = CarryDumpScript(params())
    script.start(np.array([0.0, 0.1, -0.3]))
    far = Ranges(to_hopper_m=-0.6, to_pile_m=0.5)  # the hopper's spot behind the tip
    action = script.act(state(lift=0.1), far)
    assert script.phase == "back_out"
    assert action[0] < 0 and action[1] < 0 and action[2] < 0  # back, arm up (lift falls), curl
    clear = params().clear_of_hopper_m + 1.1 - 0.30 + 0.01  # the loader's front clear of the hopper
    script.act(state(lift=0.1), Ranges(to_hopper_m=clear, to_pile_m=1.0))
    assert script.phase == "back_out", "the arm is not up yet"
    script.act(state(lift=params().carry_lift_rad), Ranges(to_hopper_m=clear, to_pile_m=1.0))
    assert script.phase == "to_hopper"


def test_to_hopper_drives_either_way_and_stops_over_the_centre():
    p = params()
    script = CarryDumpScript(p)
    script.start(np.zeros(3))
    script.phase = "to_hopper"
    up = state(lift=p.carry_lift_rad, tilt=p.carry_tilt_rad)
    assert script.act(up, Ranges(to_hopper_m=0.3, to_pile_m=1.0))[0] > 0
    assert script.act(up, Ranges(to_hopper_m=-0.3, to_pile_m=1.0))[0] < 0
    assert script.phase == "to_hopper"
    script.act(up, Ranges(to_hopper_m=0.005, to_pile_m=1.0))
    assert script.phase == "dump"


def test_dump_tips_the_bucket_and_holds_it_before_curling_back():
    p = params()
    script = CarryDumpScript(p)
    script.start(np.array([0.0, p.carry_lift_rad, p.carry_tilt_rad]))
    script.phase = "dump"
    over = Ranges(to_hopper_m=0.0, to_pile_m=1.0)
    assert script.act(state(lift=p.carry_lift_rad, tilt=p.carry_tilt_rad), over)[2] > 0  # tips down
    tipped = state(lift=p.carry_lift_rad, tilt=p.dump_tilt_rad)
    holds = 0
    while script.phase == "dump":
        script.act(tipped, over)
        holds += 1
    assert holds * p.control_period_s > p.dump_hold_s
    assert script.phase == "back_off"
    assert script.act(tipped, over)[2] < 0  # curls back
    script.act(state(lift=p.carry_lift_rad, tilt=p.carry_tilt_rad), over)
    assert script.phase == "return"


def test_return_approaches_the_pile_and_ends_start_gap_short_at_rest():
    p = params()
    script = CarryDumpScript(p)
    script.start(np.array([0.0, p.carry_lift_rad, p.carry_tilt_rad]))
    script.phase = "return"
    moving = state(speed=0.1, lift=0.23, tilt=0.0)
    assert script.act(moving, Ranges(to_hopper_m=-1.0, to_pile_m=0.8))[0] > 0
    script.act(moving, Ranges(to_hopper_m=-1.0, to_pile_m=p.start_gap_m))
    assert script.phase == "return", "still moving"
    script.act(state(speed=0.0, lift=0.23, tilt=0.0), Ranges(to_hopper_m=-1.0, to_pile_m=p.start_gap_m))
    assert script.done and not script.timed_out


def test_a_phase_that_never_ends_stops_at_its_time_limit_and_is_recorded():
    p = params(phase_limit_s=2.0)
    script = CarryDumpScript(p)
    script.start(np.zeros(3))
    stuck = Ranges(to_hopper_m=-2.0, to_pile_m=0.5)  # never clear of the hopper's spot
    steps = 0
    while script.phase == "back_out":
        script.act(state(lift=p.carry_lift_rad), stuck)
        steps += 1
    assert script.phase == "to_hopper" and script.timed_out == ["back_out"]
    assert steps == round(p.phase_limit_s / p.control_period_s) + 1
    assert PHASES[-1] == "done"


# ------------------------------------------------------------------ accounting
def test_accounting_finds_each_group_and_flags_what_fits_none():
    pile = np.array([[x, 0.0, RADIUS] for x in np.arange(0.0, 0.4, 2 * RADIUS)])
    stray = np.array([[-0.5, 0.0, RADIUS]])  # apart from the pile: spilled
    bucket = np.array([[0.2, 0.0, 0.3]])
    kept = np.array([[-6.0, -3.0, RADIUS]])
    lost = np.array([[0.0, 0.0, -1.0], [np.nan, 0.0, 0.0], [-7.0, -3.0, RADIUS]])  # under, NaN, delivered not kept
    positions = np.vstack([pile, stray, bucket, kept, lost])
    n = len(positions)
    in_bucket = np.zeros(n, bool)
    in_bucket[len(pile) + 1] = True
    delivered = np.zeros(n, bool)
    delivered[[len(pile) + 2, n - 1]] = True
    kept_mask = np.zeros(n, bool)
    kept_mask[len(pile) + 2] = True
    counts = account(positions, RADIUS, in_bucket, delivered, kept_mask).counts()
    assert counts == {"pile": len(pile), "bucket": 1, "delivered": 1, "spilled": 1, "unaccounted": 3}
    assert not account(positions, RADIUS, in_bucket, delivered, kept_mask).balanced()
    good = slice(0, n - 3)
    assert account(positions[good], RADIUS, in_bucket[good], delivered[good], kept_mask[good]).balanced()


def test_the_pile_is_the_largest_touching_cluster():
    a = np.array([[x, 0.0, RADIUS] for x in np.arange(0.0, 0.3, 2 * RADIUS)])
    b = a[:2] + [1.0, 0.0, 0.0]
    cluster = touching_cluster(np.vstack([a, b]), RADIUS, np.ones(len(a) + 2, bool))
    assert cluster.tolist() == [True] * len(a) + [False, False]


def test_the_toe_ignores_a_stray_particle_and_what_lies_beside_the_path():
    face = np.array([[x, y, z] for x in np.arange(0.3, 0.8, 0.06) for y in (-0.1, 0.0, 0.1)
                     for z in (RADIUS, 3 * RADIUS)])
    stray = np.array([[0.1, 0.0, RADIUS]])
    beside = np.array([[0.0, 0.35, RADIUS], [0.05, 0.35, 3 * RADIUS]])
    positions = np.vstack([face, stray, beside])
    everything = np.ones(len(positions), bool)
    toe = toe_x_m(positions, RADIUS, everything, 32.0, path_half_width_m=0.23)
    expected = 0.3 - RADIUS - 2.5 * RADIUS / np.tan(np.radians(32.0))
    assert toe == pytest.approx(expected)
    assert toe_x_m(positions, RADIUS, everything, 32.0, path_half_width_m=1.0) < expected
    assert np.isnan(toe_x_m(beside, RADIUS, np.ones(2, bool), 32.0, path_half_width_m=0.23)), "no pile on the path"


def test_the_profile_is_the_top_of_the_highest_particle_over_each_point():
    positions = np.array([[0.0, 0.0, RADIUS], [0.0, 0.1, 3 * RADIUS], [0.5, 0.0, RADIUS]])
    points, heights = pile_profile(positions, RADIUS, np.ones(3, bool), 0.01)
    assert heights[np.argmin(np.abs(points))] == pytest.approx(4 * RADIUS, abs=1e-3)
    assert heights[np.argmin(np.abs(points - 0.5))] == pytest.approx(2 * RADIUS, abs=1e-3)
    assert heights[np.argmin(np.abs(points - 0.25))] == 0.0


# ------------------------------------------------------------------ the scene and the hopper
def test_the_hopper_is_in_the_shift_scene_only():
    config = shift_world_config(ScoopConfig().with_overrides(SMALL_SHIFT))
    assert mujoco.mj_name2id(ScoopSim(ScoopConfig()).model, mujoco.mjtObj.mjOBJ_BODY, "hopper") == -1
    assert ShiftSim(config).model.body("hopper").mocapid[0] >= 0


def test_the_hopper_counts_what_lies_inside_it_as_delivered_and_keeps_it_apart():
    config = shift_world_config(ScoopConfig().with_overrides(SMALL_SHIFT))
    sim = ShiftSim(config)
    sim.reset(np.random.default_rng(0))
    sim.spot_hopper(-1.0)
    shift = config.shift
    inside = [np.array([-1.0 + dx, dy, 0.05]) for dx, dy in ((0.0, 0.0), (0.15, 0.2), (-0.2, -0.25))]
    outside = [np.array([-1.0 + shift.hopper_length_m / 2 + 0.1, 0.0, RADIUS]), np.array([-1.0, 0.6, RADIUS])]
    for index, position in enumerate(inside + outside):
        sim.set_particle(index, position)
    mujoco.mj_forward(sim.model, sim.data)
    assert np.flatnonzero(sim.particles_in_hopper()).tolist() == [0, 1, 2]
    assert sim.deliver() == 3
    assert np.flatnonzero(sim.delivered).tolist() == [0, 1, 2]
    assert sim.delivered_kept()[[0, 1, 2]].all() and not sim.delivered_kept()[[3, 4]].any()
    assert sim.hopper_position_m[0] < -5, "the hopper left"
    assert sim.deliver() == 0, "nothing is delivered twice"


# ------------------------------------------------------------------ a short shift
@pytest.fixture(scope="module")
def two_cycles() -> dict:
    config = ScoopConfig().with_overrides(SMALL_SHIFT)
    return run_shift(HeuristicScooper(), config, cycles=2, seed=0, progress=False)


def test_every_particle_is_accounted_for_at_the_end_of_every_cycle(two_cycles):
    for row in two_cycles["cycles"]:
        counts = row["particles"]
        assert row["conserved"] and counts["unaccounted"] == 0
        assert counts["pile"] + counts["bucket"] + counts["delivered"] + counts["spilled"] == 72
    delivered = sum(row["mass_delivered_kg"] for row in two_cycles["cycles"])
    assert delivered == pytest.approx(two_cycles["cycles"][-1]["particles"]["delivered"] * 0.3)
    assert two_cycles["totals"]["conserved"]


def test_a_shift_delivers_scoops_and_the_pile_retreats(two_cycles):
    first, second = two_cycles["cycles"]
    assert first["mass_delivered_kg"] > 0 and second["mass_delivered_kg"] > 0
    assert first["cycle_time_s"] > first["scoop_time_s"] > 0
    assert set(first["phase_times_s"]) == set(PHASES[:-1]) and not first["timed_out_phases"]
    assert 0 < first["toe_retreat_m"] < second["toe_retreat_m"]
    assert first["energy_kj"] > 0 and 0 <= first["wheel_slip"] < 0.5
    assert 0 < first["energy_scoop_kj"] < first["energy_kj"]  # the carry, dump and return spend the rest
    totals = two_cycles["totals"]
    assert totals["energy_scoop_kj"] == pytest.approx(sum(c["energy_scoop_kj"] for c in two_cycles["cycles"]))
    assert totals["energy_scoop_share"] == pytest.approx(totals["energy_scoop_kj"] / totals["energy_kj"])
    assert totals["delivered_t_per_h"] == pytest.approx(
        totals["delivered_kg"] / 1000 / (totals["shift_time_s"] / 3600))
    assert totals["energy_kj_per_t"] == pytest.approx(totals["energy_kj"] / (totals["delivered_kg"] / 1000))


# ------------------------------------------------------------------ bad input, before any simulation
@pytest.mark.parametrize(("overrides", "key"), [
    ({"shift.pile_particles": 20}, "shift.pile_particles"),
    ({"shift.hopper_height_m": 0.3}, "shift.hopper_height_m"),
    ({"shift.haul_distance_m": 0.2}, "shift.haul_distance_m"),
    ({"randomize.preset": "robot"}, "randomize.preset"),
])
def test_a_shift_that_cannot_work_is_refused_naming_the_key(overrides, key):
    with pytest.raises(ValueError, match=key.replace(".", r"\.")):
        check_shift_config(ScoopConfig().with_overrides(overrides))


def test_a_negative_haul_distance_is_refused_naming_the_key():
    with pytest.raises(ConfigError, match=r"shift\.haul_distance_m"):
        ScoopConfig().with_overrides({"shift.haul_distance_m": -0.5})


def test_the_defaults_make_a_valid_shift_of_fifteen_full_scoops():
    config = ScoopConfig()
    check_shift_config(config)
    assert config.shift.pile_particles * config.pile.particle_mass_kg >= 15 * config.reward.rated_load_kg


# ------------------------------------------------------------------ the command
def test_the_shift_command_writes_its_json_and_report(tmp_path, capsys):
    out, summary = tmp_path / "report", tmp_path / "shift.json"
    code = main(["shift", "--policy", "heuristic", "--cycles", "1", "--set", "shift.pile_particles=72",
                 "--set", "pile.variants=1", "--json", str(summary), "--out", str(out)])
    assert code == 0
    data = json.loads(summary.read_text())
    assert [s["policy"] for s in data["shifts"]] == ["heuristic"] and len(data["shifts"][0]["cycles"]) == 1
    assert data["summary"]["heuristic"]["conserved"] is True
    assert data["conditions"]["haul_distance_m"] == ScoopConfig().shift.haul_distance_m
    report = (out / "shift.md").read_text()
    assert "## Conditions" in report and "λ^2.5" in report
    assert all((out / name).stat().st_size > 0 for name in ("shift_fill_cycle_time.png", "shift_pile_profiles.png",
                                                            "shift_delivered.png"))
    assert "delivered (t/h)" in capsys.readouterr().out


@pytest.mark.parametrize(("setting", "key"), [
    ("shift.hopper_height_m=0.5", "shift.hopper_height_m"),
    ("shift.haul_distance_m=-1", "shift.haul_distance_m"),
    ("shift.pile_particles=10", "shift.pile_particles"),
])
def test_the_shift_command_refuses_bad_input_naming_the_key_before_simulating(setting, key, capsys, monkeypatch):
    def no_simulation(*args, **kwargs):
        raise AssertionError("simulated")

    monkeypatch.setattr("autoscoop.evaluation.shift.run_shift", no_simulation)
    assert main(["shift", "--policy", "heuristic", "--cycles", "1", "--set", setting]) == 2
    error = capsys.readouterr().err
    assert key in error and "Traceback" not in error


def test_the_pile_out_of_the_scoops_reach_is_held_and_the_rest_moves_freely():
    config = shift_world_config(ScoopConfig().with_overrides({"shift.pile_particles": 140, "pile.variants": 1}))
    sim = ShiftSim(config)
    sim.reset(np.random.default_rng(0))
    x = sim.particle_positions[:, 0]
    sliding = np.array([sim.model.dof_damping[sim.model.joint(f"particle_{i:03d}").dofadr[0]] for i in range(len(x))])
    assert (x > REACH_BEHIND_TOE_M).any() and (x < REACH_BEHIND_TOE_M).any()
    assert np.all(sliding[x > REACH_BEHIND_TOE_M] == HELD_DAMPING_NS_M)
    assert np.all(sliding[x < REACH_BEHIND_TOE_M] == 0.0)


@pytest.mark.skipif(not (os.environ.get("MUJOCO_GL") or has_display(os.environ)),
                    reason="no display and no off-screen OpenGL (install libosmesa6)")
def test_the_shift_command_films_the_first_shift(tmp_path):
    video = tmp_path / "shift.mp4"
    assert main(["shift", "--policy", "heuristic", "--cycles", "1", "--set", "shift.pile_particles=72",
                 "--set", "pile.variants=1", "--video", str(video)]) == 0
    import imageio.v2 as imageio

    reader = imageio.get_reader(video)
    assert reader.count_frames() > 20
    assert reader.get_data(0).shape[:2] == (432, 768)


def test_the_work_meter_splits_its_sum_by_actuator_and_counts_no_braking():
    """The meter's per-actuator sums add up to its total; a loader driving and lifting does positive work at the
    wheels and the lift, and nothing counts negative."""
    env = make_scoop_env(ScoopConfig().with_overrides({"pile.variants": 2}))
    env.reset(seed=0)
    sim = env.unwrapped.sim
    meter = WorkMeter(sim.model, sim.data)
    sim.add_substep_observer(meter)
    for _ in range(4):
        env.step(np.array([1.0, -1.0, 0.0]))
    sim.remove_substep_observer(meter)
    by_actuator = dict(zip(ACTUATORS, meter.positive_work_by_actuator_j, strict=True))
    assert meter.positive_work_j == pytest.approx(sum(by_actuator.values()))
    assert all(work >= 0.0 for work in by_actuator.values())
    assert by_actuator["lift"] > 0.0 and sum(by_actuator[name] for name in WHEELS) > 0.0
