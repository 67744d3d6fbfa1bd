"""The one-page HTML report (sim.html_report, ``stereosim run --html``): its sections, embedded
images, determinism, the report keys it reads, and a real render in headless Chromium."""

from __future__ import annotations

import base64
import copy
import hashlib
import json
import re
import shutil
import subprocess

import cv2
import numpy as np
import pytest

from stereosim.core.io import disparity_to_colour, encode_png
from stereosim.sim.api import run
from stereosim.sim.cli import main
from stereosim.sim.html_report import (
    BAD_PX,
    ERR_BAD,
    ERR_INVALID,
    ERR_UNSCORED,
    activity,
    dominant_states,
    error_image,
    histogram,
    html_report,
    latency_ns,
)
from stereosim.sim.tracing import TraceRequest

H, W, SHIFT, D = 48, 64, 3, 16
PNG_URI = re.compile(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"')
SECTIONS = ("maps", "metrics", "activity", "fifos", "timeline", "configuration")


def _pair():
    """A textured 64x48 pair whose true disparity is SHIFT everywhere."""
    rng = np.random.default_rng(7)
    base = rng.integers(0, 256, (H, W + SHIFT), dtype=np.uint8)
    return base[:, SHIFT:].copy(), base[:, :W].copy()


@pytest.fixture(scope="module")
def cycle_run():
    left, right = _pair()
    gt = np.full((H, W), float(SHIFT), dtype=np.float32)
    result = run(left, right, mode="cycle", overrides={"sva.disparities": D}, gt=gt,
                 trace=TraceRequest(timeline="unused.json"))
    return result, gt


@pytest.fixture(scope="module")
def functional_run():
    left, right = _pair()
    return run(left, right, mode="functional", overrides={"sva.disparities": D})


@pytest.fixture(scope="module")
def cycle_page(cycle_run):
    result, gt = cycle_run
    return html_report(result.report, result.disparity, gt=gt, log=result.trace)


def _images(page: str) -> list[np.ndarray]:
    out = []
    for b64 in PNG_URI.findall(page):
        data = base64.b64decode(b64)
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
        assert img is not None
        out.append(img)
    return out


# ---- accessors ---------------------------------------------------------------------------------


def test_histogram_reads_the_occupancy_bins_and_their_cycles():
    bins, counts = histogram({"occupancy_histogram": {"cycles": [5, 3, 2],
                                                      "occupancy": [0, 1, 2],
                                                      "clock_domain": "sva"}})
    assert bins.tolist() == [0, 1, 2] and counts.tolist() == [5, 3, 2]


def test_activity_reads_the_four_counts():
    entry = {"busy": 6, "starved": 2, "blocked": 1, "idle": 1, "clock_domain": "sva",
             "cycles_total": 10, "percent": {"busy": 60.0}}
    assert activity(entry) == {"busy": 6, "starved": 2, "blocked": 1, "idle": 1}
    assert activity({"busy": 0, "starved": 0, "blocked": 0, "idle": 0}) is None


def test_latency_ns_reads_us_and_ms():
    rep = {"latency": {"first_output_us": 5.5, "frame_ms": 0.0025}}
    assert latency_ns(rep) == pytest.approx((5500.0, 2500.0))
    assert latency_ns({}) is None  # functional mode


# ---- figures, by hand --------------------------------------------------------------------------


def test_error_image_colours_by_hand():
    inf = np.inf
    disp = np.array([[3.0, 3.5, 6.0, inf], [1.0, 2.0, 9.0, 4.0]], dtype=np.float32)
    gt = np.array([[3.0, 3.0, 3.0, 3.0], [inf, 1.0, 9.0, 4.0]], dtype=np.float32)
    mask = np.array([[1, 1, 1, 1], [1, 1, 1, 0]], dtype=bool)
    rgb, n = error_image(disp, gt, mask)
    assert rgb.dtype == np.uint8 and rgb.shape == (2, 4, 3)
    assert rgb[0, 0].tolist() == [0, 0, 0]  # exact
    assert rgb[0, 1].tolist() == [43] * 3  # 0.5 px: floor(170 * 0.5 / 2 + 0.5)
    assert rgb[0, 2].tolist() == list(ERR_BAD)  # 3 px > 2 px
    assert rgb[0, 3].tolist() == list(ERR_INVALID)  # no disparity, GT known
    assert rgb[1, 0].tolist() == list(ERR_UNSCORED)  # GT unknown
    assert rgb[1, 1].tolist() == [85] * 3  # 1 px: floor(170 * 1 / 2 + 0.5)
    assert rgb[1, 2].tolist() == [0, 0, 0]
    assert rgb[1, 3].tolist() == list(ERR_UNSCORED)  # outside the mask
    assert n == {"scored": 6, "bad": 1, "invalid": 1, "max_error": 3.0}
    assert BAD_PX == 2.0


def test_dominant_states_by_hand():
    # busy (1) on [0, 10), starved (2) on [10, 30), busy on [30, 40)
    t = np.array([0, 10, 30], dtype=np.int64)
    v = np.array([1, 2, 1], dtype=np.uint64)
    # [0, 16): busy 10, starved 6 -> busy; [16, 40): starved 14, busy 10 -> starved
    assert dominant_states(t, v, 40, np.array([0.0, 16.0, 40.0])).tolist() == [1, 2]
    # [25, 40): starved 5, busy 10 -> busy; [0, 25): busy 10, starved 15 -> starved
    assert dominant_states(t, v, 40, np.array([0.0, 25.0, 40.0])).tolist() == [2, 1]


# ---- the page ----------------------------------------------------------------------------------


def test_cycle_page_has_every_section_and_the_headline(cycle_run, cycle_page):
    result, _ = cycle_run
    rep = result.report
    for anchor in SECTIONS:
        assert f'id="{anchor}"' in cycle_page
    assert cycle_page.startswith("<!DOCTYPE html>") and "</html>" in cycle_page
    assert "http://" not in cycle_page and "https://" not in cycle_page  # nothing to fetch
    thr = rep["throughput"]
    assert f"{thr['fps_measured']:,.1f}</div><div class=\"k\">fps measured" in cycle_page
    assert f"{thr['fps_bound']:,.1f}</div><div class=\"k\">fps work bound (bottleneck " \
           f"{thr['bottleneck']})" in cycle_page
    lat = rep["latency"]
    assert 1.0 <= lat["first_output_us"] < lat["frame_ms"] * 1e3 < 1e3  # both shown in µs
    assert f"{lat['first_output_us']:.2f} µs</div><div class=\"k\">latency to first output" \
        in cycle_page
    assert f"{lat['frame_ms'] * 1e3:.2f} µs</div><div class=\"k\">latency of the frame" \
        in cycle_page
    energy = rep["energy"]
    assert f"{energy['per_frame_uj']['total']:.3f} µJ</div><div class=\"k\">energy per frame" \
        in cycle_page
    assert f"{energy['power_mw']:.1f} mW</div><div class=\"k\">power at" in cycle_page
    assert f"{100.0 - rep['output']['invalid_percent']:.2f}%</div><div class=\"k\">valid " \
        in cycle_page
    assert f"{rep['metrics']['all']['bad2']:.2f}%</div><div class=\"k\">bad2 (all)" in cycle_page
    assert '<td class="key">disparities</td><td>16</td>' in cycle_page
    assert '<td class="key">lr_check</td><td>true</td>' in cycle_page
    assert f"colour scale 0 to {D} px" in cycle_page
    for name in rep["blocks"]:
        assert name in cycle_page
    for name in rep["fifos"]:
        assert f'<td class="key">{name}</td>' in cycle_page
    assert "trace window" in cycle_page  # the Gantt, not the key instants


def test_cycle_page_images_decode_and_the_map_is_disparity_png(cycle_run, cycle_page):
    result, _ = cycle_run
    images = _images(cycle_page)
    # map + bar, error map + bar, blocks, SVA stages, FIFOs, Gantt
    assert len(images) == 8
    first = PNG_URI.search(cycle_page).group(1)
    assert base64.b64decode(first) == encode_png(disparity_to_colour(result.disparity, D))
    assert images[0].shape[:2] == (H, W) and images[2].shape[:2] == (H, W)
    for img in images[1:2] + images[3:]:
        assert img.shape[1] >= 400 and img.shape[0] >= 50  # charts: plausible sizes
        assert len(np.unique(img.reshape(-1, 3), axis=0)) > 20  # not a blank canvas


def test_page_is_byte_identical_across_calls(cycle_run, cycle_page):
    result, gt = cycle_run
    again = html_report(copy.deepcopy(result.report), result.disparity.copy(), gt=gt.copy(),
                        log=result.trace)
    assert again == cycle_page


def test_functional_page_without_gt_renders_what_there_is(functional_run):
    page = html_report(functional_run.report, functional_run.disparity)
    for anchor in SECTIONS:
        assert f'id="{anchor}"' in page
    assert page.count("a functional-mode run has no clock") == 3
    assert "No ground truth" in page
    assert "fps" not in re.search(r'<div class="cards">.*?</div></div></div>', page,
                                  re.DOTALL).group(0)
    images = _images(page)
    assert len(images) == 2  # the map and its colour bar
    assert page == html_report(functional_run.report, functional_run.disparity)


def test_a_gt_of_another_shape_is_refused(functional_run):
    with pytest.raises(ValueError, match=r"gt has shape \(4, 4\) but the disparity map"):
        html_report(functional_run.report, functional_run.disparity, gt=np.zeros((4, 4)))


def test_cycle_page_without_trace_shows_the_key_instants(cycle_run):
    result, _ = cycle_run
    page = html_report(result.report, result.disparity)
    assert "No ground truth" in page
    assert "key instants" in page and "trace window" not in page
    assert len(_images(page)) == 6  # map, bar, blocks, SVA stages, FIFOs, key instants


# ---- the command line --------------------------------------------------------------------------


def _write_pair(tmp_path):
    left, right = _pair()
    lp, rp = tmp_path / "l.png", tmp_path / "r.png"
    lp.write_bytes(encode_png(left))
    rp.write_bytes(encode_png(right))
    return lp, rp


def test_run_html_is_part_of_the_output_set(tmp_path, monkeypatch, capsys):
    lp, rp = _write_pair(tmp_path)
    monkeypatch.chdir(tmp_path)
    code = main(["run", "--left", str(lp), "--right", str(rp), "--disparities", str(D),
                 "--out", "out", "--html", "page.html"])
    stdout = capsys.readouterr().out
    assert code == 0 and "wrote page.html" in stdout
    data = (tmp_path / "page.html").read_bytes()
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["files"]["../page.html"] == hashlib.sha256(data).hexdigest()
    page = data.decode("utf-8")
    assert 'id="activity"' in page and "l.png + " in page
    first = base64.b64decode(PNG_URI.search(page).group(1))
    assert first == (tmp_path / "out" / "disparity.png").read_bytes()
    assert main(["run", "--left", str(lp), "--right", str(rp), "--disparities", str(D),
                 "--out", "out2", "--html", "page2.html"]) == 0
    assert (tmp_path / "page2.html").read_bytes() == data


def test_run_html_refuses_a_stream_and_a_folder(tmp_path, monkeypatch, capsys):
    lp, rp = _write_pair(tmp_path)
    monkeypatch.chdir(tmp_path)
    base = ["run", "--left", str(lp), "--right", str(rp), "--disparities", str(D), "--out", "o"]
    assert main(base + ["--html", "p.html", "--frames", "2"]) == 2
    assert "--html reports one frame" in capsys.readouterr().err
    (tmp_path / "adir").mkdir()
    assert main(base + ["--html", "adir"]) == 2
    assert "--html path adir is a folder" in capsys.readouterr().err
    assert not (tmp_path / "o").exists() and not (tmp_path / "p.html").exists()


# ---- acceptance: a real browser ----------------------------------------------------------------


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def test_page_renders_in_headless_chromium(cycle_run, cycle_page, tmp_path):
    browser = _chromium()
    if browser is None:
        pytest.skip("no chromium, chromium-browser or google-chrome on PATH (apt install "
                    "chromium) to render the HTML report")
    page = tmp_path / "report.html"
    page.write_text(cycle_page, encoding="utf-8")
    shot = tmp_path / "shot.png"
    cmd = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
           "--no-first-run", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", "--hide-scrollbars", f"--user-data-dir={tmp_path / 'profile'}",
           "--window-size=1200,3000", f"--screenshot={shot}", page.as_uri()]
    proc = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert shot.is_file()
    img = cv2.imread(str(shot), cv2.IMREAD_COLOR)
    assert img is not None and img.shape == (3000, 1200, 3)
    pixels = img.reshape(-1, 3)
    non_white = np.any(pixels < 245, axis=1).mean()
    assert non_white > 0.10, f"only {non_white:.1%} of the screenshot is not white"
    assert len(np.unique(pixels, axis=0)) > 500  # maps, bars and charts, not a blank page
    # the disparity map, shown scaled up: its commonest colour covers a large area
    colours, counts = np.unique(disparity_to_colour(cycle_run[0].disparity, D).reshape(-1, 3),
                                axis=0, return_counts=True)
    common = colours[np.argmax(counts)].astype(int)
    assert common.tolist() != [0, 0, 0]
    near = np.all(np.abs(pixels.astype(int) - common[::-1]) <= 8, axis=1).sum()
    share = counts.max() / counts.sum()
    assert near > 0.5 * share * 640 * 480, f"only {near} pixels show the map's commonest colour"
    # saturated colours (map, colour bar, activity bars): far more than text could give
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV).reshape(-1, 3)
    assert np.count_nonzero((hsv[:, 1] > 120) & (hsv[:, 2] > 80)) > 100_000


def test_cycle_page_shows_the_chips_area(cycle_run, cycle_page):
    """The area section: chip_area of the run's plan, each row of area_rows, escaped."""
    import html as html_text

    from stereosim.core.config import load_config
    from stereosim.sim.cycle.area import area_rows, chip_area
    from stereosim.sim.cycle.plan import build_plan

    result, _ = cycle_run
    area = chip_area(build_plan(load_config(None, {"sva.disparities": D}), (H, W)), "45nm")
    assert result.report["area"] == area
    assert '<h2 id="area">Area</h2>' in cycle_page
    for what, figs in area_rows(area):
        assert (f'<td class="key">{html_text.escape(what)}</td><td>{html_text.escape(figs)}'
                "</td>") in cycle_page
    old = {k: v for k, v in result.report.items() if k != "area"}  # an older report.json
    assert 'id="area"' not in html_report(old, result.disparity)
