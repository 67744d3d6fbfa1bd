"""core.heap: glibc keeps a frame's freed arrays for the next one (no page faults the second
time), and the switch that turns it off."""

import os
import subprocess
import sys
import textwrap

import pytest

from stereosim.core import heap

GLIBC = sys.platform.startswith("linux") and os.confstr("CS_GNU_LIBC_VERSION") is not None

# allocate and touch a 12 MiB array, free it, three times; print the page faults of each
PROBE = textwrap.dedent("""
    import resource
    import numpy as np
    from stereosim.core import heap
    print(heap.keep_freed_memory())
    for _ in range(3):
        before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        a = np.ones(12 << 20, np.uint8)
        del a
        print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
""")


def probe(env_value=None):
    env = dict(os.environ)
    env.pop(heap.ENV, None)
    if env_value is not None:
        env[heap.ENV] = env_value
    done = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                          env=env, timeout=120, check=True)
    first, *faults = done.stdout.split()
    return first == "True", [int(f) for f in faults]


@pytest.mark.skipif(not GLIBC, reason="mallopt is glibc's: elsewhere core.heap changes nothing")
def test_a_freed_frame_array_is_reused_without_page_faults():
    """The first array faults its pages in (fewer than 3,072 where numpy asks for huge
    pages); with the thresholds raised the next two reuse the freed block, where glibc by
    default unmaps it and the second faults its pages in again."""
    took, faults = probe()
    assert took
    assert faults[0] > 100
    assert max(faults[1:]) < faults[0] // 10
    took, faults = probe("0")
    assert not took
    assert faults[1] > faults[0] // 2

