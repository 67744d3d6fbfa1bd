"""Published stereo accelerators (configs/published/chips.json, docs/published-chips.md): every
entry is cited with the figures looked for, its configuration loads and holds the published
figures it can express, and stereosim's estimate gives its configuration a frame rate."""

import json
from functools import reduce
from pathlib import Path

import pytest

from stereosim.core.config import load_config
from stereosim.sim.cycle.estimate import estimate

PUBLISHED = Path(__file__).resolve().parents[2] / "configs" / "published"
CHIPS = json.loads((PUBLISHED / "chips.json").read_text())["chips"]
NAMES = [chip["name"] for chip in CHIPS]

#: The figures every entry records: a value with where it was found, or null with why not.
FIGURES = ("node_nm", "fpga_part", "width", "height", "disparities", "paths", "clock_mhz",
           "fps", "area_mm2", "power_mw")
VERIFIED = {"abstract", "repository", "derived"}
#: Published figures that a configuration must hold whenever the publication gives them.
EXPRESSIBLE = {"disparities": "sva.disparities", "paths": "sva.paths",
               "clock_mhz": "clocks.sva_mhz", "width": "source.camera_width",
               "height": "source.camera_height"}


def _chip(name):
    return next(chip for chip in CHIPS if chip["name"] == name)


def _config(chip):
    return load_config(PUBLISHED / chip["config"])


def _get(cfg, dotted):
    return reduce(getattr, dotted.split("."), cfg)


def test_every_published_config_has_one_entry():
    files = sorted(p.name for p in PUBLISHED.glob("*.toml"))
    assert sorted(chip["config"] for chip in CHIPS) == files
    assert len(set(NAMES)) == len(NAMES) >= 3


@pytest.mark.parametrize("name", NAMES)
def test_entry_is_cited(name):
    cite = _chip(name)["citation"]
    for field in ("authors", "title", "venue"):
        assert isinstance(cite[field], str) and cite[field].strip(), field
    assert 1990 < cite["year"] < 2100
    assert cite["source_urls"] and all(u.strip() for u in cite["source_urls"])


@pytest.mark.parametrize("name", NAMES)
def test_entry_records_node_and_figures(name):
    chip = _chip(name)
    figures = chip["figures"]
    assert set(FIGURES) <= set(figures)
    for key, fig in figures.items():
        if fig["value"] is None:
            assert fig["why"].strip(), f"{name}: {key} is null without a reason"
            continue
        assert fig["verified"] in VERIFIED, f"{name}: {key}"
        text = fig.get("derivation") if fig["verified"] == "derived" else fig.get("where")
        assert text and text.strip(), f"{name}: {key} says neither where nor how"
    assert figures["node_nm"]["value"] or figures["fpga_part"]["value"]
    assert chip["kind"] in ("asic", "fpga")
    if chip["kind"] == "asic":
        assert figures["node_nm"]["value"] > 0
    assert figures["fps"]["value"] > 0
    assert figures["area_mm2"]["value"] or figures["power_mw"]["value"] or chip["kind"] == "fpga"
    assert chip["frame_size"] == [figures["width"]["value"], figures["height"]["value"]]


@pytest.mark.parametrize("name", NAMES)
def test_config_holds_the_published_figures_it_can_express(name):
    chip = _chip(name)
    cfg = _config(chip)
    keys = chip["config_keys"]
    for figure, dotted in EXPRESSIBLE.items():  # a published D, paths or clock is never skipped
        if chip["figures"][figure]["value"] is not None:
            assert keys.get(figure) == dotted, f"{name}: {figure} is published but not checked"
    assert keys, name
    for figure, dotted in keys.items():
        published = chip["figures"][figure]["value"]
        assert published is not None, f"{name}: {figure} maps to {dotted} but has no value"
        if isinstance(published, list):
            published = tuple(published)
        assert _get(cfg, dotted) == published, f"{name}: {dotted}"
    width, height = chip["frame_size"]
    assert (cfg.source.camera_width, cfg.source.camera_height) == (width, height)


@pytest.mark.parametrize("name", NAMES)
def test_estimate_gives_the_configuration_a_frame_rate(name):
    chip = _chip(name)
    cfg = _config(chip)
    width, height = chip["frame_size"]
    est = estimate(cfg, (height, width))
    assert est["image"] == {"height": height, "width": width}
    thr = est["throughput"]
    assert thr["fps_bound"] > 0 and thr["fps_delivered"] > 0
    assert thr["fps_delivered"] <= thr["fps_bound"]
    print(f"{name}: published {chip['figures']['fps']['value']} fps; stereosim estimate "
          f"{thr['fps_delivered']:.3f} fps (bottleneck {thr['bottleneck']})")
