"""Config: defaults, checked ranges with clear errors, YAML and --set overrides."""

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
    ("pile.angle_deg", "80", "allowed [15.0, 60.0]"),
    ("pile.n_particles", "0", "allowed [1, 400]"),
    ("pile.n_particles", "2.5", "must be an integer"),
    ("pile.radius_m", "nan", "must be a number"),
    ("robot.start_gap_m", "-1", "robot.start_gap_m"),
    ("env.mass_source", "scale", "choose one of"),
])
def test_bad_values_name_the_key_and_range(key, value, fragment):
    with pytest.raises(ConfigError) as error:
        ScoopConfig().with_overrides({key: value})
    assert key in str(error.value) and fragment in str(error.value)


def test_unknown_key_is_refused_with_the_known_keys():
    with pytest.raises(ConfigError, match="unknown config key 'pile.angel_deg'.*pile.angle_deg"):
        ScoopConfig().with_overrides({"pile.angel_deg": 30})


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
    env = gym.make("autoscoop/Scoop-v0", **{"pile.angle_deg": 25, "env.max_episode_s": 2.0})
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
        gym.make("autoscoop/Scoop-v0", **{"pile.angle_deg": 5})


def test_angle_mix_gives_each_pile_variant_one_of_the_angles():
    from autoscoop.envs.scoop import ScoopEnv

    env = ScoopEnv(**{"pile.angle_mix_deg": "[25, 40]", "pile.variants": 4})
    angles = set()
    for seed in range(12):
        _, info = env.reset(seed=seed)
        angles.add(info["pile_angle_deg"])
    assert angles == {25.0, 40.0}
    with pytest.raises(ConfigError, match=r"pile.angle_mix_deg holds 70.0, out of range; allowed \[15.0, 60.0\]"):
        ScoopConfig().with_overrides({"pile.angle_mix_deg": "[25, 70]"})


def test_a_yaml_file_overrides_only_the_keys_it_sets(tmp_path):
    from autoscoop.core.config import overrides_from_yaml

    (tmp_path / "c.yaml").write_text("pile:\n  angle_deg: 28\nenv.max_episode_s: 6\n")
    assert overrides_from_yaml(tmp_path / "c.yaml") == {"pile.angle_deg": 28, "env.max_episode_s": 6}
    (tmp_path / "bad.yaml").write_text("pile: 3\n")
    with pytest.raises(ConfigError, match="section 'pile' must be a mapping"):
        overrides_from_yaml(tmp_path / "bad.yaml")
