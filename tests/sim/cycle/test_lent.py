"""The network on the lent NNA submodules (nna.lent_network, sim/cycle/lent.py): its figures in
exact numbers from the docstring's rules on small networks, stride, spill, the weight store,
the cut into submodules against every cut, the file's checks (one line; exit 2 from the CLI),
and what the stereo pair loses on the DRAM channel, measured by the cycle model."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError
from stereosim.core.io import encode_png
from stereosim.nna.geometry import buffer_rows, share_macs, strided_size
from stereosim.sim.cli import main
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.lent import _group_cycles, cut_layers, lent_lines, lent_report
from stereosim.sim.cycle.plan import MAX_RUN_FS, build_plan

H, W = 8, 40
# census with a 4-row line buffer (window 3, slack 1): a stereo submodule's line-buffer SRAM is
# 4 x 40 x 8 = 1280 bits, and it has no weight store
CENSUS = {"clocks.nna_mhz": 400, "clocks.sva_mhz": 400, "sva.disparities": 16,
          "nna.descriptor": "census", "nna.line_buffer_rows": 4, "nna.macs": 16}
# 16x12x2 -> 3x3/2 2->4 -> 8x6x4 -> 1x1/1 4->8 -> 8x6x8
NET = [(3, 2, 4, 2), (1, 4, 8, 1)]


def _plan(path, lent=1, **over):
    cfg = load_config(overrides={**CENSUS, "nna.lent_submodules": lent,
                                 "nna.lent_network": path, **over})
    return build_plan(cfg, (H, W))


def test_stride_gives_ceil_outputs_and_a_strides_rows_of_slack():
    assert [strided_size(7, s) for s in (1, 2, 3, 4)] == [7, 4, 3, 2]
    assert buffer_rows((3, 3, 1, 5), (1, 2, 1, 4), 1) == (4, 5, 2, 9)
    assert buffer_rows((9,), (1,), 0) == (9,)


def test_one_submodule_in_exact_figures(tmp_path, lent_toml):
    """On one submodule of 16 MACs: m = 72, 32 MACs a pixel, 48 output pixels each; shares in
    proportion to m items = 3456, 1536: floors 11, 4, the one left to the larger remainder
    (4608 > 384 of 4992): 11, 5 -> 7, 7 cycles a pixel, 336 cycles a frame. Line buffers: 5
    rows x 16 x 2 x 8 = 1280 bits (fits the 1280), 2 x 8 x 4 x 8 = 512 (does not: spills its
    8 x 6 x 4 input, written and read, 384 bytes). DRAM: input 384, output 384, spill 384,
    weights 72 + 32 + 8 x (4 + 8) = 200 read each frame (no weight store)."""
    plan = _plan(lent_toml(tmp_path / "n.toml", NET, channels=2, height=12))
    lent = plan.lent
    assert [(lay.in_shape, lay.out_shape) for lay in lent.layers] == [((12, 16), (6, 8)),
                                                                       ((6, 8), (6, 8))]
    assert [(lay.share, lay.ii, lay.rows, lay.buffer_bits, lay.on_chip)
            for lay in lent.layers] == [(11, 7, 5, 1280, True), (5, 7, 2, 512, False)]
    assert lent.sram_budget_bits == 1280 and lent.weight_store_bits == 0
    assert lent.frame_cycles == 336 and lent.used == 1
    assert lent.fps_max == pytest.approx(400e6 / 336) and lent.fps == lent.fps_max
    assert lent.bytes_per_frame == {"input": 384, "output": 384, "spill": 384, "weights": 200}
    assert lent.gbps == pytest.approx(1352 * 400e6 / 336 / 1e9)
    assert lent.macs_per_frame == 48 * 72 + 48 * 32


def test_two_submodules_one_layer_each_and_no_spill(tmp_path, lent_toml):
    """Two submodules: each layer alone on 16 MACs, ceil(72 / 16) = 5 and ceil(32 / 16) = 2
    cycles a pixel, 240 and 96 cycles a frame (the cut beats 336); both buffers fit."""
    plan = _plan(lent_toml(tmp_path / "n.toml", NET, channels=2, height=12), lent=2)
    lent = plan.lent
    assert [(lay.submodule, lay.share, lay.ii, lay.on_chip) for lay in lent.layers] == [
        (0, 16, 5, True), (1, 16, 2, True)]
    assert lent.submodule_cycles == (240, 96) and lent.frame_cycles == 240
    assert lent.bytes_per_frame["spill"] == 0
    # a third submodule has no layer to take
    assert _plan(lent_toml(tmp_path / "n.toml", NET, channels=2, height=12), lent=3,
                 **{"nna.submodules": 10}).lent.used == 2


def test_a_weight_store_holds_small_weights_and_a_target_sets_the_traffic(tmp_path, lent_toml):
    """The CNN's submodule keeps 9x9x32 weights: 200 bytes fit, none are read per frame; at
    a target of 1000 fps the traffic is 768 bytes x 1000."""
    path = lent_toml(tmp_path / "n.toml", NET, channels=2, height=12, fps=1000)
    plan = _plan(path, **{"nna.descriptor": "cnn", "nna.line_buffer_rows": 10})
    lent = plan.lent
    assert lent.weight_store_bits > 8 * 200 and lent.weights_resident(0)
    assert lent.sram_budget_bits == 10 * 40 * 8  # both buffers fit: no spill
    assert lent.bytes_per_frame == {"input": 384, "output": 384, "spill": 0, "weights": 0}
    assert lent.fps == 1000 and lent.gbps == pytest.approx(768e3 / 1e9)


def test_the_cut_is_the_best_of_every_cut():
    """Against every contiguous cut into at most N groups (the naive search)."""
    rng = np.random.default_rng(3)
    for _ in range(25):
        n = int(rng.integers(1, 6))
        items = [int(x) for x in rng.integers(1, 300, n)]
        mpp = [int(x) for x in rng.integers(1, 5000, n)]
        macs, subs = int(rng.integers(n, 64)), int(rng.integers(1, 5))
        best = None
        for g in range(1, min(subs, n) + 1):
            for cuts in itertools.combinations(range(1, n), g - 1):
                edges = (0, *cuts, n)
                worst = max(_group_cycles(items[a:b], mpp[a:b], macs)[0]
                            for a, b in itertools.pairwise(edges))
                best = worst if best is None else min(best, worst)
        got = cut_layers(items, mpp, macs, subs)
        groups = [[i for i in range(n) if got[i] == s] for s in range(got[-1] + 1)]
        assert all(g == list(range(g[0], g[-1] + 1)) for g in groups)
        assert max(_group_cycles([items[i] for i in g], [mpp[i] for i in g], macs)[0]
                   for g in groups) == best
    # shares are weighted by work, not by MACs a pixel alone
    assert share_macs(10, (100 * 1, 1 * 100)) == (5, 5)


@pytest.mark.parametrize("text, needle", [
    ("fps = 30\n[input]\nwidth = 8\nheight = 8\nchannels = 1\n", "layer is missing"),
    ("fps = 30\n[input]\nwidth = 8\nheight = 8\n[[layer]]\nkernel = 3\nchannels_in = 1\n"
     "channels_out = 4\nstride = 1\n", "input.channels is missing"),
    ("fps = 30\n[input]\nwidth = 8\nheight = 8\nchannels = 1\n[[layer]]\nkernel = 4\n"
     "channels_in = 1\nchannels_out = 4\nstride = 1\n", r"layer\[0\].kernel must be odd"),
    ("fps = 30\n[input]\nwidth = 8\nheight = 8\nchannels = 1\n[[layer]]\nkernel = 3\n"
     "channels_in = 1\nchannels_out = 4\nstride = 1\n[[layer]]\nkernel = 3\nchannels_in = 8\n"
     "channels_out = 4\nstride = 5\n", r"layer\[1\].stride must be in \[1, 4\]"),
    ("fps = 30\n[input]\nwidth = 8\nheight = 8\nchannels = 1\n[[layer]]\nkernel = 3\n"
     "channels_in = 1\nchannels_out = 4\nstride = 1\n[[layer]]\nkernel = 3\nchannels_in = 8\n"
     "channels_out = 4\nstride = 1\n",
     r"layer\[1\].channels_in = 8 must equal layer\[0\].channels_out = 4"),
    ("fps = \"fast\"\n[input]\nwidth = 8\nheight = 8\nchannels = 1\n[[layer]]\nkernel = 3\n"
     "channels_in = 1\nchannels_out = 4\nstride = 1\n", "fps must be a number"),
    ("fps = 30\nsize = 3\n", "unknown key size"),
    ("fps = 30\n[input]\nwidth = 8\nheight = 8\nchannels = 1\n[[layer]]\nkernel = 3\n"
     "channels_in = 1\nchannels_out = 4\nstride = 1\nrelu = true\n",
     r"unknown key layer\[0\].relu"),
    ("fps = 1e6\n[input]\nwidth = 8\nheight = 8\nchannels = 1\n[[layer]]\nkernel = 3\n"
     "channels_in = 1\nchannels_out = 4\nstride = 1\n", "but it reaches only 520833.333 fps"),
])
def test_a_bad_file_is_refused_in_one_line_naming_the_field(tmp_path, text, needle, capsys):
    """The last case: 64 output pixels of ceil(36 / 16) = 3 cycles, 192 cycles a frame at
    100 MHz: 520,833.333 fps at most, below the 1e6 it asks for."""
    path = tmp_path / "bad.toml"
    path.write_text(text)
    over = {**CENSUS, "nna.lent_submodules": 1, "nna.lent_network": str(path),
            "nna.macs": 16, "clocks.nna_mhz": 100}
    with pytest.raises(ConfigError, match=needle) as err:
        build_plan(load_config(overrides=over), (H, W))
    assert "\n" not in str(err.value) and "bad.toml" in str(err.value)
    sets = [a for k, v in over.items() for a in ("--set", f"{k}={v}")]
    assert main(["estimate", "--size", f"{W}x{H}", *sets]) == 2
    err_text = capsys.readouterr().err.strip()
    assert len(err_text.splitlines()) == 1 and "bad.toml" in err_text


def test_the_reports_show_it(tmp_path, lent_toml, capsys):
    path = lent_toml(tmp_path / "n.toml", NET, channels=2, height=12)
    sets = [a for k, v in {**CENSUS, "nna.lent_submodules": 2, "nna.lent_network": path,
                           "dram.model": "tdm"}.items() for a in ("--set", f"{k}={v}")]
    assert main(["estimate", "--size", f"{W}x{H}", "--json", *sets]) == 0
    est = json.loads(capsys.readouterr().out)["lent_network"]
    assert est["cycles_per_frame"] == 240 and est["submodules_used"] == 2
    assert est["dram_bytes_per_frame"]["total"] == 968
    st = est["stereo_pair"]
    assert st["read_bound_fps"] < st["read_bound_fps_without_lent"]
    assert main(["config", "plan", "--size", f"{W}x{H}", *sets]) == 0
    assert "lent network" in capsys.readouterr().out


CAMERAS = {"dram.gbps": 1.0, "source.kind": "camera", "source.frame_buffers": 2,
           "clocks.camera_mhz": 50, "source.camera_hblank": 4, "source.camera_vblank": 2}


@pytest.mark.parametrize("over, fps", [({"dram.gbps": 0.2}, 1e5), (CAMERAS, 3e5)],
                         ids=["memory", "camera_frame_buffers"])
def test_the_stereo_pair_loses_dram_slots_and_time(tmp_path, lent_toml, over, fps):
    """On a narrow channel the lent network's slots lengthen every round, so the stereo pair's
    reads come slower and its frame finishes later (the same words). Read from memory at 0.2
    GB/s, the reads bound the chip: 968 bytes at 1e5 fps = 0.0968 GB/s, x = 0.484 of the
    channel, ceil(x 4 / (1 - x)) = 4 lent slots beside the 4 of the read and the write-back,
    so the work bound halves. From cameras writing into DRAM frame buffers the camera bounds
    the chip and the frame ends later by the last bursts' longer rounds. The energy section
    prices the lent network's MACs at its fps over the stereo frame's time."""
    cfg = {**CENSUS, "dram.model": "tdm", "dram.burst_bytes": 16, **over}
    path = lent_toml(tmp_path / "n.toml", NET, channels=2, height=12, fps=fps)
    rng = np.random.default_rng(0)
    base = rng.integers(0, 256, (H, W + 3), dtype=np.uint8)
    left, right = base[:, :W].copy(), base[:, 3:].copy()
    alone = build_plan(load_config(overrides=cfg), (H, W))
    shared = _plan(path, lent=2, **{k: v for k, v in cfg.items() if k not in CENSUS})
    lent_slots = shared.dram.client("lent").count
    assert shared.dram.round_slots == alone.dram.round_slots + lent_slots
    res0, res1 = run_compiled(alone, left, right), run_compiled(shared, left, right)
    r0, r1 = res0.report, res1.report
    t0, t1 = (r["cycles"]["last_output"]["time_ms"] for r in (r0, r1))
    assert t1 > t0
    np.testing.assert_array_equal(res0.words, res1.words)
    st = lent_report(shared.lent, shared.dram, H * W)["stereo_pair"]
    assert st["lent_slots_per_round"] == lent_slots
    assert st["read_bound_fps_without_lent"] == r0["dram"]["read_bound_fps"]
    assert st["read_bound_fps"] == r1["dram"]["read_bound_fps"]
    if "source.kind" not in over:
        assert lent_slots == 4
        assert r1["throughput"]["fps_bound"] == pytest.approx(r0["throughput"]["fps_bound"] / 2,
                                                              rel=1e-3)
    items = [it for it in r1["energy"]["items"] if it["block"] == "lent"]
    macs = next(it for it in items if it["action"] == "mac")
    seconds = r1["cycles"]["total"]["nna"] / shared.domains["nna"].freq_hz
    assert macs["count"] == round(fps * seconds * shared.lent.macs_per_frame)
    assert {it["action"] for it in items} == {"mac", "multiply", "sram_read", "sram_write",
                                              "dram"}


@pytest.mark.parametrize("fps", [1e-320, 1e-6], ids=["no_client", "no_slot"])
def test_a_traffic_too_light_for_a_slot_is_not_called_no_channel(tmp_path, lent_toml, fps):
    """A lent network whose traffic rounds to nothing (0 GB/s: the channel gets no lent
    client; or a client of no slot) was reported as "dram.model = none": the channel is
    modelled, and the report says the traffic takes no slot of it."""
    path = lent_toml(tmp_path / "n.toml", NET, channels=2, height=12, fps=fps)
    plan = _plan(path, lent=2, **{"dram.model": "tdm"})
    client = plan.dram.client("lent")
    assert client is None or client.count == 0
    st = lent_report(plan.lent, plan.dram, H * W)["stereo_pair"]
    assert st["dram_channel"] is True and st["lent_slots_per_round"] == 0
    assert st["read_bound_fps"] == st["read_bound_fps_without_lent"]
    assert "dram.model" not in st["note"] and "takes no slot" in st["note"]
    lines = lent_lines(lent_report(plan.lent, plan.dram, H * W))
    assert not any("dram.model = none" in line for line in lines)
    assert "takes no slot of the DRAM channel's round" in lines[-1]
    none = _plan(path, lent=2)  # no channel modelled: that is what it says then
    assert "dram.model = none" in lent_report(none.lent, none.dram, H * W)["stereo_pair"]["note"]


# A tiny network whose traffic leaves the stereo pair a sliver of a channel just wider: 137
# bytes a frame (input 64, output 64, weights 9) at 7e6 fps is 0.959 GB/s
SLIVER_NET = [(1, 1, 1, 1)]
SLIVER_GBPS = 137 * 7e6 / 1e9


@pytest.mark.parametrize("sliver", [1e-8, 1e-9])
def test_a_lent_network_that_starves_the_pair_gives_a_result_or_one_line(tmp_path, lent_toml,
                                                                         capsys, sliver):
    """The lent client takes all but a part in 1e8 (1e9) of the channel: the automatic budget
    (20x a run of 1,121 s of chip time) overflowed the compiled engine's int64 femtoseconds
    with a traceback. Now the budget is capped to MAX_RUN_FS and the frame completes (1e8:
    about 640 s of chip time), or the run, expected to take longer than the engines simulate
    (1e9: 11,212 s), is refused in one line naming the DRAM slots."""
    path = lent_toml(tmp_path / "n.toml", SLIVER_NET, width=8, height=8, fps=7e6)
    over = {"dram.model": "tdm", "dram.gbps": SLIVER_GBPS * (1 + sliver),
            "nna.lent_submodules": 4, "nna.lent_network": path, "sva.disparities": 16,
            "nna.descriptor": "census"}
    plan = build_plan(load_config(overrides=over), (24, 64))
    assert plan.budget_reason == "time_limit"
    rng = np.random.default_rng(0)
    lp, rp = tmp_path / "l.png", tmp_path / "r.png"
    base = rng.integers(0, 256, (24, 67), dtype=np.uint8)
    lp.write_bytes(encode_png(base[:, :64].copy()))
    rp.write_bytes(encode_png(base[:, 3:].copy()))
    sets = [a for k, v in over.items() for a in ("--set", f"{k}={v}")]
    code = main(["run", "--left", str(lp), "--right", str(rp), "--out", str(tmp_path / "out"),
                 "--json", *sets])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    if sliver == 1e-8:
        assert code == 0
        report = json.loads(out)
        seconds = report["cycles"]["total"]["nna"] / plan.domains["nna"].freq_hz
        assert 100 < seconds < MAX_RUN_FS / 1e15
    else:
        lines = [ln for ln in err.splitlines() if not ln.startswith("stereosim: compiling")]
        assert code == 2 and len(lines) == 1, err
        assert "longer than the 2,305.843 s the cycle engines simulate" in lines[0]
        assert "the stereo pair's reads get 2 of the DRAM channel's" in lines[0]
