import dataclasses
import itertools

import numpy as np
import pytest

from stereosim.core.config import (
    AUTO_BUDGET_FACTOR,
    DESCRIPTOR_DEFAULTS,
    ChipConfig,
    check,
    check_config,
    config_diff,
    config_to_toml,
    load_config,
    parse_set_options,
    sgm_widths,
)
from stereosim.core.errors import ConfigError
from stereosim.nna.census_unit.census import census, census_bits
from stereosim.nna.conv.weights import save_weights
from stereosim.nna.descriptor import compute_descriptor, descriptor_bits
from stereosim.sim.api import run
from stereosim.sim.cycle import plan as plan_module
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.spec import resolve_chip
from stereosim.sva.box.aggregation import box_filter
from stereosim.sva.hamming.cost import hamming_cost
from stereosim.sva.pipeline.pipeline import SvaStream


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


def test_sgm_widths_are_the_narrowest_that_hold_a_path_cost():
    for box, p2 in itertools.product((3, 5, 7), (0, 223, 224, 512, 1247, 1248, 1792, 2047)):
        w = sgm_widths(p2, box)
        cost = box * box * 32  # the largest k x k box of 32-bit Hamming costs
        assert 2 ** (w["cost_bits"] - 1) <= cost < 2 ** w["cost_bits"]
        top = cost + p2  # plus the P2 jump
        assert 2 ** (w["path_bits"] - 1) <= top < 2 ** w["path_bits"]
        assert 2 ** (w["sum_bits"] - 1) <= 4 * (2 ** w["path_bits"] - 1) < 2 ** w["sum_bits"]
    for descriptor, tuned in DESCRIPTOR_DEFAULTS.items():
        cfg = load_config(None, {"nna.descriptor": descriptor}).sva
        # the hybrid's largest cost: its weights times its parts' bits (32 CNN + 32 census)
        top = 32 * sum(cfg.cost_weights) if descriptor == "hybrid" else 32
        widths = sgm_widths(tuned["p2"], cfg.box_size, top)
        assert (cfg.cost_bits, cfg.path_bits, cfg.sum_bits) == tuple(widths.values())


@pytest.mark.parametrize(("over", "widths"), [
    ({"sva.box_size": 9}, (12, 13, 15)),                    # 2592 < 2^12; + 1792 < 2^13
    ({"sva.box_size": 3, "sva.p2": 100}, (9, 9, 11)),       # 288 < 2^9; 388 < 2^9
    ({"sva.paths": 2}, (11, 12, 13)),                       # 2 x 4095 < 2^13
    ({"sva.box_size": 1, "sva.p2": 0}, (6, 8, 8)),  # 32 needs 6 bits: path at its floor 8
    ({"sva.box_size": 15, "sva.p2": 30000}, (13, 14, 16)),  # 7200 + 30000 needs 16: capped at 14
    ({"sva.box_size": 9, "sva.cost_bits": 10}, (10, 13, 15)),  # a width set by the user wins
    # a plain 9x7 census has 62 bits: 62 x 49 = 3038 < 2^12; + its P2 2048 < 2^13
    ({"nna.descriptor": "census", "nna.census.window": [9, 7]}, (12, 13, 15)),
    ({"nna.descriptor": "census", "nna.census.window": [3, 3]}, (9, 12, 14)),  # 8 x 49 = 392
    ({"nna.cnn.channels": 48}, (12, 13, 15)),               # 48 x 49 = 2352 < 2^12
])
def test_unset_widths_follow_the_configured_box_p2_and_paths(over, widths):
    sva = load_config(None, {"nna.descriptor": "cnn", **over}).sva
    assert (sva.cost_bits, sva.path_bits, sva.sum_bits) == widths


def test_derived_widths_are_written_as_auto_and_follow_a_reload(tmp_path):
    cfg = load_config(None, {"sva.box_size": 9})
    text = config_to_toml(cfg, set_keys={"sva.box_size"})
    assert "# cost_bits = 12" in text and "auto: the narrowest" in text
    saved = tmp_path / "chip.toml"
    saved.write_text(text.replace("box_size = 9", "box_size = 3"))
    assert load_config(saved).sva.cost_bits == 9  # re-derived for the new box, not pinned at 12


@pytest.mark.parametrize("window, kind", [((9, 7), "plain"), ((15, 7), "symmetric"),
                                          ((5, 3), "plain")])
def test_census_registers_hold_its_own_largest_cost(window, kind):
    """The widths follow the census's bit count, not a 32-bit descriptor's: a pair whose right
    view is the left one inverted differs in nearly every bit at every disparity, and its
    box-filtered cost stays below the cost register's ceiling (where it would saturate)."""
    over = {"nna.descriptor": "census", "nna.census.window": list(window), "nna.census.kind": kind}
    sva = load_config(None, over).sva
    bits = census_bits(window, kind)
    left = np.random.default_rng(3).integers(0, 256, (32, 64), dtype=np.uint8)
    dl, dr = census(left, window, kind), census(255 - left, window, kind)
    cost = box_filter(hamming_cost(dl, dr, 16, bits), sva.box_size, sva.cost_bits)
    ceiling = 2 ** sva.cost_bits - 1
    assert sva.box_size ** 2 * bits <= ceiling < 2 * sva.box_size ** 2 * bits
    assert 0.9 * sva.box_size ** 2 * bits < cost.max() < ceiling


def test_a_wider_cnn_layer_sets_its_channels_and_its_registers_hold_its_largest_cost(tmp_path):
    """A 48-channel layer runs only with ``nna.cnn.channels = 48`` (else one line saying so);
    the registers then follow 48 bits: a pair whose views differ in every bit of the descriptor
    reaches box^2 x 48 without saturating the cost register."""
    weights = np.zeros((48, 3, 3), np.int8)
    weights[:, 1, 1] = 1  # every channel is the sign of the centre pixel minus 128
    path = tmp_path / "wide.npz"
    save_weights(path, weights, np.zeros(48, np.int32), 128)
    left = np.random.default_rng(5).integers(0, 256, (24, 64), dtype=np.uint8)
    left = np.where(left < 128, 0, 255).astype(np.uint8)
    over = {"nna.descriptor": "cnn", "nna.cnn.weights": str(path), "sva.disparities": 16}
    with pytest.raises(ConfigError, match=r"has 48 output channels but nna.cnn.channels is 32: "
                                          r"set nna.cnn.channels = 48"):
        run(left, 255 - left, mode="functional", overrides=over)
    cfg = load_config(None, {**over, "nna.cnn.channels": 48})
    sva, nna = cfg.sva, cfg.nna
    assert descriptor_bits(nna) == 48 and sva.cost_bits == (sva.box_size ** 2 * 48).bit_length()
    dl, dr = compute_descriptor(left, nna), compute_descriptor(255 - left, nna)
    cost = box_filter(hamming_cost(dl, dr, 16, 48), sva.box_size, sva.cost_bits)
    assert cost.max() == sva.box_size ** 2 * 48 < 2 ** sva.cost_bits - 1


@pytest.mark.parametrize("descriptor", sorted(DESCRIPTOR_DEFAULTS))
def test_default_sgm_registers_never_saturate(descriptor):
    """At each descriptor's defaults the disparities equal those of registers two bits wider
    on a random pair (high costs everywhere; that the widths are also the narrowest is the
    arithmetic of the test above)."""
    rng = np.random.default_rng(7)
    left = rng.integers(0, 256, (24, 96), dtype=np.uint8)
    right = rng.integers(0, 256, (24, 96), dtype=np.uint8)
    base = {"nna.descriptor": descriptor, "sva.disparities": 32}
    cfg = load_config(None, base).sva

    def disparity(**widths):
        over = {**base, **{f"sva.{k}": v for k, v in widths.items()}}
        return run(left, right, mode="functional", overrides=over).disparity_fixed

    shipped = disparity()
    # two bits wider, up to each register's widest (the hybrid's path register is at its 14)
    assert np.array_equal(shipped, disparity(cost_bits=min(cfg.cost_bits + 2, 15),
                                             path_bits=min(cfg.path_bits + 2, 14),
                                             sum_bits=min(cfg.sum_bits + 2, 16)))
    assert not np.array_equal(shipped, disparity(path_bits=8, sum_bits=8))  # saturation shows


def test_a_configuration_is_checked_where_it_enters_and_trusted_after(monkeypatch):
    """stereosim.run checks the configuration it is given once, at its entry, and hands the
    resolved spec down (build_plan, the NNA's and the SVA's entry points take it as checked).
    No object is remembered as checked: each entry checks a raw configuration or section it is
    given, so a bad one (dataclasses.replace) is refused at every entry."""
    cfg = load_config(overrides={"sva.disparities": 16, "nna.submodules": 2})
    built = []
    build = check._build
    monkeypatch.setattr(check, "_build", lambda cls, data, prefix: (
        built.append(prefix), build(cls, data, prefix))[1])
    check_config(cfg)
    one_check = list(built)  # the chip, then each section it nests
    assert one_check[0] == "" and "nna." in one_check and "sva." in one_check
    rng = np.random.default_rng(3)
    left = rng.integers(0, 256, (24, 64), dtype=np.uint8)
    right = np.roll(left, -2, axis=1)
    built.clear()
    functional = run(left, right, mode="functional", config=cfg)
    assert built[:len(one_check)] == one_check  # the chip, at the run's entry
    assert built.count("") == 1 and built.count("sva.") == 1  # the SVA ran on the spec
    built.clear()
    cycle = run(left, right, mode="cycle", config=cfg)
    assert built[:len(one_check)] == one_check and built.count("") == 1
    assert (functional.disparity_fixed == cycle.disparity_fixed).all()
    # below the entry: the spec is trusted, a raw section checked
    chip = resolve_chip(cfg)
    built.clear()
    desc = compute_descriptor(left, chip.nna)
    SvaStream(desc, desc, left, chip.sva, chip.nna.part_bits)
    assert built == []
    compute_descriptor(left, cfg.nna)
    SvaStream(desc, desc, left, cfg.sva, chip.nna.part_bits)
    assert built == ["nna.", "nna.census.", "nna.cnn.", "sva."]
    bad = dataclasses.replace(cfg, sva=dataclasses.replace(cfg.sva, paths=5))
    for entry in (lambda: build_plan(bad, left.shape),
                  lambda: resolve_chip(bad),
                  lambda: SvaStream(desc, desc, left, bad.sva, 32),
                  lambda: compute_descriptor(left, dataclasses.replace(cfg.nna, macs=0))):
        with pytest.raises(ConfigError, match=r"must be in \[1, "):
            entry()
    numpy_p1 = dataclasses.replace(cfg, sva=dataclasses.replace(cfg.sva, p1=np.int64(9)))
    fixed = check_config(numpy_p1)
    assert type(fixed.sva.p1) is int and fixed.sva.p1 == 9 and check_config(fixed) == fixed


def test_the_budget_factor_is_quoted_from_its_constant(monkeypatch):
    """The automatic budget's factor is one constant: the help of sim.max_cycles and the line of
    a run that exhausts it quote it, and the budget scales with it."""
    cfg = load_config(overrides={"sva.disparities": 16})
    plan = build_plan(cfg, (24, 64))
    assert f"({AUTO_BUDGET_FACTOR}x the expected run) ran out" in plan.budget_remedy
    (max_cycles,) = [f for f in dataclasses.fields(cfg.sim) if f.name == "max_cycles"]
    assert f"budget of {AUTO_BUDGET_FACTOR}x the expected run" in max_cycles.metadata["help"]
    monkeypatch.setattr(plan_module, "AUTO_BUDGET_FACTOR", 2 * AUTO_BUDGET_FACTOR)
    doubled = build_plan(cfg, (24, 64)).budget
    for domain, cycles in plan.budget.items():
        assert abs((doubled[domain] - 100_000) - 2 * (cycles - 100_000)) <= 1
