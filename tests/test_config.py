"""Config: defaults, checked ranges with clear errors, YAML and --set overrides."""

import re

import gymnasium as gym
import pytest

import autoscoop  # noqa: F401  (registers the environment)
from autoscoop.core.config import ConfigError, ScoopConfig, all_keys, load_yaml, parse_set_args, save_yaml

REQUIRED_KEYS = ["pile.angle_deg", "pile.n_particles", "pile.radius_m", "pile.particle_mass_kg", "pile.friction",
                 "robot.start_gap_m", "env.control_period_s", "env.max_episode_s"]


def test_required_keys_exist_with_paper_defaults():
    assert set(REQUIRED_KEYS) <= set(all_keys())
    c = ScoopConfig()
    assert (c.pile.angle_deg, c.pile.n_particles, c.pile.radius_m, c.pile.particle_mass_kg) == (32.0, 72, 0.034, 0.3)
    assert (c.env.control_period_s, c.env.max_episode_s, c.max_episode_steps) == (0.25, 8.0, 32)


@pytest.mark.parametrize("key, value, fragment", [
    ("pile.angle_deg", "80", "pile.angle_deg = 80: Input should be less than or equal to 60 (allowed [15.0, 60.0] deg)"),
    ("pile.n_particles", "0", "pile.n_particles = 0: Input should be greater than or equal to 1 (allowed [1, 1000])"),
    ("pile.n_particles", "2.5", "pile.n_particles = 2.5: Input should be a valid integer (allowed [1, 1000])"),
    ("pile.radius_m", "nan", "pile.radius_m = 'nan': Input should be a valid number (allowed [0.01, 0.08] m)"),
    ("pile.radius_m", float("nan"), "pile.radius_m = nan: Input should be a finite number (allowed [0.01, 0.08] m)"),
    ("robot.start_gap_m", "-1", "robot.start_gap_m = -1: Input should be greater than or equal to 0"),
    ("env.mass_source", "scale", "env.mass_source = 'scale': Input should be 'truth' or 'torque'"),
])
def test_bad_values_name_the_key_and_range(key, value, fragment):
    with pytest.raises(ConfigError) as error:
        ScoopConfig().with_overrides({key: value})
    assert key in str(error.value) and fragment in str(error.value)


def test_unknown_key_is_refused_with_the_nearest_or_the_known_keys():
    with pytest.raises(ConfigError, match="unknown config key 'pile.angel_deg'; did you mean pile.angle_deg or"):
        ScoopConfig().with_overrides({"pile.angel_deg": 30})
    with pytest.raises(ConfigError, match="unknown config key 'pile.zzzzzz'; known in pile: angle_deg, angle_mix_deg,"):
        ScoopConfig().with_overrides({"pile.zzzzzz": 30})
    with pytest.raises(ConfigError, match="unknown config key 'zzz'; known sections: robot, pile, reward"):
        ScoopConfig().with_overrides({"zzz": 30})


def test_yaml_round_trip_and_dotted_keys(tmp_path):
    config = ScoopConfig().with_overrides(parse_set_args(["pile.angle_deg=28", "reward.c_w=5"]))
    save_yaml(config, tmp_path / "c.yaml")
    assert load_yaml(tmp_path / "c.yaml") == config
    (tmp_path / "d.yaml").write_text("pile.angle_deg: 40\nenv:\n  max_episode_s: 6\n")
    loaded = load_yaml(tmp_path / "d.yaml")
    assert (loaded.pile.angle_deg, loaded.env.max_episode_s) == (40.0, 6.0)


def test_set_argument_needs_key_and_value():
    with pytest.raises(ConfigError, match="key=value"):
        parse_set_args(["pile.angle_deg"])


def test_gym_make_takes_overrides_and_sets_the_time_limit():
    env = gym.make("autoscoop/Scoop-v1", **{"pile.angle_deg": 25, "env.max_episode_s": 2.0})
    assert env.unwrapped.config.pile.angle_deg == 25.0
    env.reset(seed=0)
    steps = 0
    while True:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample() * 0)
        steps += 1
        if terminated or truncated:
            break
    assert steps == 8 and truncated
    with pytest.raises(ConfigError, match="pile.angle_deg"):
        gym.make("autoscoop/Scoop-v1", **{"pile.angle_deg": 5})


def test_angle_mix_gives_each_pile_variant_one_of_the_angles():
    from autoscoop.envs.scoop import ScoopEnv

    env = ScoopEnv(**{"pile.angle_mix_deg": "[25, 40]", "pile.variants": 4})
    angles = set()
    for seed in range(12):
        _, info = env.reset(seed=seed)
        angles.add(info["pile_angle_deg"])
    assert angles == {25.0, 40.0}
    with pytest.raises(ConfigError, match=re.escape("pile.angle_mix_deg[1] = 70: Input should be less than or equal "
                                                   "to 60 (allowed [15.0, 60.0] deg)")):
        ScoopConfig().with_overrides({"pile.angle_mix_deg": "[25, 70]"})


def test_a_yaml_file_overrides_only_the_keys_it_sets(tmp_path):
    from autoscoop.core.config import overrides_from_yaml

    (tmp_path / "c.yaml").write_text("pile:\n  angle_deg: 28\nenv.max_episode_s: 6\n")
    assert overrides_from_yaml(tmp_path / "c.yaml") == {"pile.angle_deg": 28, "env.max_episode_s": 6}
    (tmp_path / "bad.yaml").write_text("pile: 3\n")
    with pytest.raises(ConfigError, match="section 'pile' must be a mapping"):
        overrides_from_yaml(tmp_path / "bad.yaml")


def test_the_physics_step_must_divide_the_control_period():
    with pytest.raises(ConfigError, match=r"env\.control_period_s = 0\.25 s must be a whole number of env\.timestep_s = 0\.03"):
        ScoopConfig().with_overrides({"env.timestep_s": 0.03})  # 8.33 steps, was 8 silently
    with pytest.raises(ConfigError, match=r"env\.control_period_s.*env\.timestep_s"):
        ScoopConfig().with_overrides({"env.control_period_s": 0.1})
    assert ScoopConfig().with_overrides({"env.timestep_s": 0.025}).substeps == 10
    assert ScoopConfig().substeps == 12
    step = ScoopConfig().env.timestep_s
    assert ScoopConfig().with_overrides({"env.control_period_s": 3 * step}).substeps == 3  # float products pass


def test_ints_become_floats_and_the_checks_are_strict():
    c = ScoopConfig().with_overrides({"pile.angle_deg": 28, "pile.angle_mix_deg": [25, 40], "reward.c_w": "5"})
    assert type(c.pile.angle_deg) is float and type(c.reward.c_w) is float
    assert c.pile.angle_mix_deg == (25.0, 40.0) and all(type(a) is float for a in c.pile.angle_mix_deg)
    assert type(c.pile.n_particles) is int
    for key, value, fragment in [("pile.angle_deg", True, "Input should be a valid number (allowed [15.0, 60.0] deg)"),
                                 ("pile.n_particles", 3.0, "Input should be a valid integer (allowed [1, 1000])"),
                                 ("pile.rolling", 1, "Input should be a valid boolean"),
                                 ("pile.angle_mix_deg", 30, "Input should be a valid tuple (allowed [15.0, 60.0] deg)")]:
        with pytest.raises(ConfigError, match=re.escape(f"{key} = {value!r}: {fragment}")):
            ScoopConfig().with_overrides({key: value})


def test_sections_built_directly_or_replaced_are_checked_too():
    from autoscoop.core.config import PileConfig, from_dict

    c = ScoopConfig()
    smaller = c.replace(pile=c.pile.replace(n_particles=40, variants=1))
    assert (smaller.pile.n_particles, smaller.pile.variants, c.pile.n_particles) == (40, 1, 72)
    assert smaller.robot == c.robot and smaller != c
    with pytest.raises(ConfigError, match=re.escape("pile.angle_deg = 80: Input should be less than or equal to 60 "
                                                   "(allowed [15.0, 60.0] deg)")):
        c.pile.replace(angle_deg=80)
    with pytest.raises(ConfigError, match=re.escape("pile.angle_deg = 80: Input should be less than or equal to 60")):
        PileConfig(angle_deg=80)
    with pytest.raises(ConfigError, match=re.escape("pile.n_particles = 0: Input should be greater than or equal to 1 "
                                                   "(allowed [1, 1000])")):
        ScoopConfig(pile={"n_particles": 0})
    with pytest.raises(ConfigError, match=r"env\.timestep_s"):
        c.replace(env=c.env.replace(timestep_s=0.03))
    with pytest.raises(ConfigError, match=re.escape("unknown config key(s) ['pile.angel_deg']; known in pile: ['angle_deg'")):
        from_dict({"pile": {"angel_deg": 30}})
    with pytest.raises(ConfigError, match=re.escape("unknown config section(s) ['piles']; known: ['robot', 'pile'")):
        from_dict({"piles": {}})
    assert from_dict({"pile": None, "env": {"max_episode_s": 6}}) == c.with_overrides({"env.max_episode_s": 6.0})


def test_to_dict_and_describe_cover_every_key_and_the_yaml_round_trips(tmp_path):
    c = ScoopConfig().with_overrides({"pile.angle_mix_deg": [25, 40], "env.mass_source": "torque"})
    flat = [f"{section}.{key}" for section, values in c.to_dict().items() for key in values]
    assert flat == all_keys()
    assert c.to_dict()["pile"]["angle_mix_deg"] == [25.0, 40.0]
    assert [row.split()[0] for row in c.describe().splitlines()] == all_keys()
    assert "pile.angle_deg" in c.describe() and "[15.0, 60.0]" in c.describe() and "deg" in c.describe()
    save_yaml(c, tmp_path / "c.yaml")
    assert load_yaml(tmp_path / "c.yaml") == c
    assert (c.max_episode_steps, c.substeps) == (32, 12)
