"""core.heap: glibc keeps a frame's freed arrays for the next one (no memory faulted in the
second time), and the switch that turns it off."""

import os
import subprocess
import sys
import textwrap

import pytest

from stereosim.core import heap

GLIBC = sys.platform.startswith("linux") and os.confstr("CS_GNU_LIBC_VERSION") is not None
ARRAY = 12 << 20  # bytes: above glibc's default mmap threshold, below core.heap's

# allocate and touch a 12 MiB array, free it, three times; print the resident bytes each array
# added (/proc/self/statm: bytes, whatever the page size, huge pages included)
PROBE = textwrap.dedent(f"""
    import os
    import numpy as np
    from stereosim.core import heap
    print(heap.keep_freed_memory())
    page = os.sysconf("SC_PAGE_SIZE")
    def resident():
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * page
    for _ in range(3):
        before = resident()
        a = np.ones({ARRAY}, np.uint8)
        print(resident() - before)
        del a
""")


def probe(env_value=None):
    env = dict(os.environ)
    env.pop(heap.ENV, None)
    if env_value is not None:
        env[heap.ENV] = env_value
    done = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                          env=env, timeout=120, check=True)
    first, *grown = done.stdout.split()
    return first == "True", [int(g) for g in grown]


@pytest.mark.skipif(not GLIBC, reason="mallopt is glibc's: elsewhere core.heap changes nothing")
def test_a_freed_frame_array_is_reused_without_faulting_memory_in():
    """The first array's pages are faulted in (the process's resident memory grows by about
    its size); with the thresholds raised the next two reuse the freed block and the process
    grows by nothing, where glibc by default unmaps the first (an mmap'd block) and faults the
    second's pages in again (its dynamic threshold then keeps the third)."""
    took, grown = probe()
    assert took
    assert grown[0] > ARRAY // 2
    assert max(grown[1:]) < ARRAY // 8
    took, grown = probe("0")
    assert not took
    assert grown[0] > ARRAY // 2
    assert grown[1] > ARRAY // 2
