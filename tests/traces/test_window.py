"""The one window syntax of `run --trace-window` and `wave --window` (traces.window), and its
resolution into femtoseconds for a chip plan (sim.tracing.window_fs)."""

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.tracing import window_fs
from stereosim.traces.window import Window, parse_window


@pytest.mark.parametrize("spec, want", [
    (None, Window("sva", None, None)),
    ("0:100us", Window("time", 0, 100 * 10**9)),
    ("1.5ns:2.25ns", Window("time", 1_500_000, 2_250_000)),
    ("0.5ps:1ps", Window("time", 500, 1000)),
    ("2us:", Window("time", 2 * 10**9, None)),
    (":40us", Window("time", None, 40 * 10**9)),
    ("1ms:0.002s", Window("time", 10**12, 2 * 10**12)),
    ("100fs:3ps", Window("time", 100, 3000)),
    ("0:3000", Window("sva", 0, 3000)),
    ("sva:10:20", Window("sva", 10, 20)),
    ("nna:0:300", Window("nna", 0, 300)),
    ("camera::8", Window("camera", None, 8)),
    ("rows:0:12", Window("rows", 0, 12)),
    (" 5 : 9 ", Window("sva", 5, 9)),
])
def test_windows_parse(spec, want):
    assert parse_window(spec) == want


def test_bare_numbers_take_the_commands_default():
    assert parse_window("100:2000", default="units", kinds=()) == Window("units", 100, 2000)
    assert parse_window("1ns:2ns", default="units", kinds=()) == Window("time", 10**6, 2 * 10**6)


@pytest.mark.parametrize("spec, message", [
    ("5", "expected A:B"),
    ("1:2:3:4", "expected A:B"),
    ("gpu:0:3", "KIND one of sva, nna, camera, rows"),
    ("9:3", "is empty: need 0 <= A < B"),
    ("3us:1us", "is empty"),
    ("abc:3", "is not a number with an optional unit"),
    ("-1:3", "is not a number"),
    ("1:3hz", "is not a number"),
    ("1.5:3", "whole numbers"),
    ("nna:0:3us", "nna bounds count cycles"),
    ("rows:0.5:3", "rows bounds count rows"),
    ("100:2us", "mixes a time and a bare number"),
])
def test_bad_windows_fail_in_one_line(spec, message):
    with pytest.raises(ConfigError, match=message) as exc:
        parse_window(spec)
    text = str(exc.value)
    assert "\n" not in text and text.startswith(f"--trace-window {spec!r}")


def test_windows_resolve_to_femtoseconds():
    plan = build_plan(load_config(overrides={"sva.disparities": 16}), (8, 24))
    sva = plan.domains["sva"].period_fs
    nna = plan.domains["nna"].period_fs
    assert window_fs("0:100us", plan) == (0, 100 * 10**9)
    assert window_fs("1.5us:2us", plan) == (1_500_000_000, 2 * 10**9)
    assert window_fs("10:20", plan) == (10 * sva, 20 * sva)
    assert window_fs("nna:3:7", plan) == (3 * nna, 7 * nna)
    assert window_fs("2us:", plan) == (2 * 10**9, 1 << 62)
    row_times = np.array([[10 * k for k in range(9)], [1000 + 10 * k for k in range(9)]])
    assert window_fs("rows:2:5", plan, row_times) == (20, 1000 + 50 + 1)
    with pytest.raises(ConfigError, match="rows 0 to 7"):
        window_fs("rows:0:9", plan, row_times)
    with pytest.raises(ConfigError, match="rows 0 to 7"):
        window_fs("rows:8:", plan, row_times)


@pytest.mark.parametrize("spec, message", [
    ("0:" + "9" * 5000 + "us", "a bound of 5000 characters, more than a window can span"),
    ("sva:0:" + "9" * 34, r"a bound of 9{34} cycles is above 2\*\*63 - 1"),
    ("0:" + "9" * 20 + "s", r"a bound of 9{20}0{15} fs is above 2\*\*63 - 1"),
    ("x" + "1" * 5000 + ":3", r"bound 'x1{59}'\.\.\. \(5001 characters\) is not a number"),
], ids=["5000 digits", "34 digits of cycles", "20 digits of seconds", "5000 characters"])
def test_huge_bounds_fail_in_one_short_line(spec, message):
    """Not a traceback (int() refuses 4300 digits; the engine counts in int64) and not the
    5,000 characters quoted back."""
    for kinds in ((), ("sva", "nna", "camera", "rows")):
        with pytest.raises(ConfigError, match=message) as exc:
            parse_window(spec, kinds=kinds if "sva:" not in spec else ("sva",))
        assert "\n" not in str(exc.value) and len(str(exc.value)) < 400


def test_cycle_windows_past_any_run():
    """A cycle bound below 2**63 whose instant (cycles x period) is not: the end is the run's,
    a start there is refused in one line."""
    plan = build_plan(load_config(overrides={"sva.disparities": 16}), (8, 24))
    assert window_fs("sva:0:" + str(2**62), plan) == (0, 1 << 62)
    with pytest.raises(ConfigError, match=r"starts at \d+ fs, after any run has ended"):
        window_fs(f"sva:{2**61}:", plan)
