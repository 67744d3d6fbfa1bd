import pytest

from sim.config import (
    ChipConfig,
    config_diff,
    config_to_toml,
    load_config,
    parse_set_options,
)
from sim.errors import ConfigError


def test_defaults_round_trip_through_toml(tmp_path):
    cfg = load_config(overrides={"sva.p1": 7, "nna.census.window": [5, 5]})
    path = tmp_path / "c.toml"
    path.write_text(config_to_toml(cfg))
    assert load_config(path) == cfg
    default = ChipConfig()
    assert config_diff(cfg, default) == {
        "sva.p1": (7, default.sva.p1),
        "nna.census.window": ([5, 5], list(default.nna.census.window)),
    }


def test_cli_strings_are_parsed_as_toml_values():
    over = parse_set_options(["sva.lr_check=false", "sva.subpixel=parabola", "sva.p2 = 300"])
    cfg = load_config(overrides=over)
    assert cfg.sva.lr_check is False
    assert cfg.sva.subpixel == "parabola"
    assert cfg.sva.p2 == 300


@pytest.mark.parametrize(
    "over, words",
    [
        ({"sva.foo": 1}, "unknown config key 'sva.foo'"),
        ({"nna.census.bogus": 1}, "unknown config key 'nna.census.bogus'"),
        ({"bogus.x": 1}, "unknown config key 'bogus'"),
        ({"sva.disparities": 100}, "'sva.disparities' must be one of"),
        ({"sva.box_size": 4}, "'sva.box_size' must be odd"),
        ({"sva.paths": 5}, "'sva.paths' must be in [1, 4]"),
        ({"sva.p1": "many"}, "'sva.p1' must be an integer"),
        ({"sva.lr_check": 1}, "'sva.lr_check' must be true or false"),
        ({"nna.census.window": [9]}, "'nna.census.window' must be a list of 2"),
        ({"sva": 3}, "'sva' is a table"),
        ({"sva.p1.x": 3}, "'sva.p1' is a value"),
    ],
)
def test_bad_keys_and_values_name_the_dotted_key(over, words):
    with pytest.raises(ConfigError) as exc:
        load_config(overrides=over)
    assert words in str(exc.value)
    assert "\n" not in str(exc.value)


def test_bad_files(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_config(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[sva\np1 = ")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(bad)
    with pytest.raises(ConfigError, match="KEY=VALUE"):
        parse_set_options(["sva.p1"])
