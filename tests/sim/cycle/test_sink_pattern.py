"""The sink's pattern (sim.cycle.rules.sink_pattern and the rules both engines apply to it)
against its definition: the sink may pop in cycle c iff script[c % P]."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stereosim.sim.cycle.rules import (
    sink_allowed_between,
    sink_may_pop,
    sink_next_allowed,
    sink_pattern,
)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.booleans(), min_size=1, max_size=40).filter(any), st.integers(0, 200))
def test_a_script_means_what_it_says(script, cycle):
    pattern = sink_pattern(script)
    p = len(script)
    assert bool(sink_may_pop(cycle, pattern)) == script[cycle % p]
    nxt = next(c for c in range(cycle, cycle + 2 * p) if script[c % p])
    assert sink_next_allowed(cycle, pattern) == nxt
    for lo in (0, cycle // 2, cycle):
        assert sink_allowed_between(lo, cycle + 7, pattern) == sum(
            script[c % p] for c in range(lo, cycle + 7))


@pytest.mark.parametrize("period, phase", [(1, 0), (4, 1), (7, 6), (1 << 40, (1 << 40) - 1)])
def test_a_periodic_pattern_is_the_script_with_one_allowed_phase(period, phase):
    pattern = sink_pattern((period, phase))
    for c in (0, phase, phase + 1, 3 * period + phase, 5 * period - 1):
        assert bool(sink_may_pop(c, pattern)) == (c % period == phase)
        assert sink_next_allowed(c, pattern) == c + (phase - c) % period
    assert sink_allowed_between(0, 3 * period, pattern) == 3


def test_no_pattern_and_period_zero_pop_in_every_cycle():
    for stall in (None, (0, 0)):
        pattern = sink_pattern(stall)
        assert all(sink_may_pop(c, pattern) for c in range(9))
        assert sink_allowed_between(3, 12, pattern) == 9


@pytest.mark.parametrize("bad", [[], [0, 0], [[1]], [2, 1], (3, 3), (-1, 0)])
def test_a_pattern_that_never_pops_or_is_malformed_is_refused(bad):
    with pytest.raises(ValueError):
        sink_pattern(np.array(bad) if isinstance(bad, list) else bad)
