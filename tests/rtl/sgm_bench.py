"""cocotb test module: the RTL SGM path units and path sum (sva/sgm/sva_sgm.sv) against stereosim.

A random aggregated volume A and grey image per run are streamed through the stage in raster
order with random input gaps and random lock-step stalls (``en`` low: nothing moves, the tick
does not count). Every pixel's path costs must equal sva/sgm/sgm.py's ``sgm_ref`` path by path
(path k: sgm_ref over the first k + 1 paths less sgm_ref over the first k, at a sum width that
never saturates) and its sums S ``sgm_ref`` at the configured widths; the path costs must leave
the plan's sgm latency after the pixel was taken, the sums the plan's path_sum latency after
them, and a pixel offered back to back be taken one plan's sgm II after the one before
(sim.cycle.stages.sva_stages, read at run time).
"""


import cocotb
import numpy as np
from cocotb.triggers import ReadOnly, RisingEdge
from twin import Pins, each_run

from stereosim.core.config import load_config
from stereosim.sim.cycle.stages import sva_stages
from stereosim.sva.sgm.sgm import sgm_ref


def pack(values, width: int) -> int:
    return sum(int(v) << (i * width) for i, v in enumerate(values))


def references(agg, img, s) -> tuple[np.ndarray, np.ndarray]:
    """(S at the configured widths, L (paths, H, W, D) path by path) from sgm_ref."""
    kw = {"p1": s.p1, "p2": s.p2, "path_bits": s.path_bits, "img": img,
          "p2_adaptive": s.p2_adaptive, "p2_slope": s.p2_slope}
    total = sgm_ref(agg, paths=s.paths, sum_bits=s.sum_bits, **kw)
    wide = [np.zeros(agg.shape, np.int64)] + [
        sgm_ref(agg, paths=n, sum_bits=16, **kw).astype(np.int64) for n in range(1, s.paths + 1)]
    return total, np.stack([wide[n + 1] - wide[n] for n in range(s.paths)])


@cocotb.test()
async def paths_sums_and_cycles(dut):
    """Every run of the case (volumes, D, P1/P2, adaptive P2, paths) on the one build."""
    await each_run(dut, one_run)


async def one_run(dut, p: dict) -> None:
    pins = Pins(dut, p.get("prefix", ""))
    cfg = load_config(overrides=p["overrides"])
    s = cfg.sva
    h, w, dn = p["h"], p["w"], s.disparities
    stages = {st.name: st for st in sva_stages(cfg, w, (32,), 16, 32)}
    sgm, psum = stages["sgm"], stages["path_sum"]
    ps_latency, ps_rule = psum.latency, f"the plan's path_sum latency ({psum.formula})"
    sgm_rule = f"the plan's sgm latency ({sgm.formula})"
    rng = np.random.default_rng(p["seed"])
    a_w, path_w, sum_w, d_max = p["a_w"], s.path_bits, s.sum_bits, p["d_max"]
    agg = rng.integers(0, int(rng.integers(8, 1 << a_w)) + 1, (h, w, dn)).astype(np.uint16)
    img = rng.integers(0, 256, (h, w)).astype(np.uint8)
    want_s, want_l = references(agg, img, s)
    g = -(-dn // s.lanes)
    dut.rst.value = 1
    pins.en.value = 1
    pins.in_valid.value = 0
    for name, value in (("ngroups", g), ("dn", dn), ("width", w), ("p1", s.p1), ("p2", s.p2),
                        ("adaptive", int(s.p2_adaptive)), ("slope", s.p2_slope),
                        ("paths", s.paths)):
        getattr(pins, name).value = value
    await RisingEdge(dut.clk)
    dut.rst.value = 0
    pixels = [(y, x) for y in range(h) for x in range(w)]
    taken, lcs, sums, back_to_back = [], [], [], []
    tick = cycle = nxt = 0
    pending_since = None
    while len(sums) < len(pixels) and cycle < 40 * len(pixels) * (g + 6):
        en = rng.random() >= p["stall"]
        pins.en.value = int(en)
        if pending_since is None and nxt < len(pixels) and rng.random() < p["offer"]:
            pending_since = tick
        if pending_since is not None:
            y, x = pixels[nxt]
            up = img[max(y - 1, 0)]
            pins.in_valid.value = 1
            pins.a.value = pack(agg[y, x], a_w)
            pins.grey.value = int(img[y, x])
            pins.grey_up.value = pack([up[max(x - 1, 0)], up[x], up[min(x + 1, w - 1)]], 8)
            pins.x_first.value = int(x == 0)
            pins.x_last.value = int(x == w - 1)
            pins.y_first.value = int(y == 0)
        else:
            pins.in_valid.value = 0
        await ReadOnly()
        if en and int(pins.lc_valid.value):
            word = int(pins.lc.value)
            lcs.append((tick, [[(word >> ((k * d_max + d) * path_w)) & ((1 << path_w) - 1)
                                for d in range(dn)] for k in range(s.paths)]))
        if en and int(pins.s_valid.value):
            word = int(pins.s.value)
            sums.append((tick, [(word >> (d * sum_w)) & ((1 << sum_w) - 1) for d in range(dn)]))
        if en and pending_since is not None and int(pins.in_ready.value):
            if taken and pending_since <= taken[-1] + 1:  # offered from the next tick on
                back_to_back.append(tick - taken[-1])
            taken.append(tick)
            nxt += 1
            pending_since = None
        await RisingEdge(dut.clk)
        cycle += 1
        tick += int(en)
    assert len(lcs) == len(sums) == len(pixels), (
        f"{len(lcs)} path costs and {len(sums)} sums of {len(pixels)} pixels left the stage")
    for (y, x), t_in, (t_lc, got_l), (t_s, got_s) in zip(pixels, taken, lcs, sums, strict=True):
        for k in range(s.paths):
            assert got_l[k] == want_l[k, y, x].tolist(), (
                f"pixel ({y}, {x}) path {k}: costs {got_l[k]} != sgm_ref's "
                f"{want_l[k, y, x].tolist()}")
        assert got_s == want_s[y, x].tolist(), (
            f"pixel ({y}, {x}): sums {got_s} != sgm_ref {want_s[y, x].tolist()}")
        assert t_lc - t_in == sgm.latency, (
            f"pixel ({y}, {x}): taken at tick {t_in}, path costs out at {t_lc}: "
            f"{t_lc - t_in} ticks, {sgm_rule} is {sgm.latency}")
        assert t_s - t_lc == ps_latency, (
            f"pixel ({y}, {x}): path costs at tick {t_lc}, sums at {t_s}: {t_s - t_lc} "
            f"ticks, {ps_rule} is {ps_latency}")
    gaps = np.diff(taken)
    assert gaps.min() >= sgm.ii, (
        f"two pixels {gaps.min()} ticks apart, the plan's sgm II is {sgm.ii} ({sgm.formula})")
    assert back_to_back and set(back_to_back) == {sgm.ii}, (
        f"pixels offered back to back were taken {sorted(set(back_to_back))} ticks apart, "
        f"the plan's sgm II is {sgm.ii} ({sgm.formula})")
