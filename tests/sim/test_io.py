import os
import struct
from pathlib import Path

import cv2
import numpy as np
import pytest

from sim.datasets import shared_data_dir
from sim.errors import InputError
from sim.io import (
    disparity_to_colour,
    encode_png,
    read_gt,
    read_image,
    read_mask,
    read_pfm,
    to_grey,
    write_disparity_png,
    write_pfm,
)

DATA = shared_data_dir()
needs_data = pytest.mark.skipif(
    DATA is None, reason="shared Middlebury data not found (set STEREOSIM_DATA or add ../shared)"
)


def _write_png_bgr(path: Path, arr: np.ndarray) -> None:
    ok, buf = cv2.imencode(".png", arr)
    assert ok
    path.write_bytes(buf.tobytes())


# ---------------------------------------------------------------- PFM


def test_pfm_round_trip_keeps_values_inf_and_row_order(tmp_path):
    arr = np.array([[0.0, 1.5, np.inf], [-2.25, 1e-7, 3.0e5]], dtype=np.float32)
    path = tmp_path / "d.pfm"
    write_pfm(path, arr)
    data = path.read_bytes()
    assert data.startswith(b"Pf\n3 2\n-1.0\n")
    # Bottom row first in the file, little-endian.
    assert struct.unpack("<3f", data[12:24]) == tuple(float(v) for v in arr[1])
    back = read_pfm(path)
    assert back.dtype == np.float32
    assert back.shape == (2, 3)
    np.testing.assert_array_equal(back, arr)
    assert np.isposinf(back[0, 2])


def test_pfm_big_endian_hand_built(tmp_path):
    # 2 wide, 3 high; rows stored bottom-to-top, big-endian because the scale is positive.
    bottom, middle, top = (5.0, 6.0), (3.0, 4.0), (1.0, float("inf"))
    body = b"".join(struct.pack(">2f", *row) for row in (bottom, middle, top))
    path = tmp_path / "be.pfm"
    path.write_bytes(b"Pf\n2 3\n1.0\n" + body)
    out = read_pfm(path)
    np.testing.assert_array_equal(out, np.array([top, middle, bottom], dtype=np.float32))
    assert out.dtype == np.float32 and out.dtype.isnative and out.flags.writeable


def test_pfm_scale_magnitude_is_ignored(tmp_path):
    # Middlebury's files say -0.003922; OpenCV would divide by it (values 255x too large).
    values = np.array([[10.0, 62.875]], dtype=np.float32)
    path = tmp_path / "mb.pfm"
    path.write_bytes(b"Pf\n2 1\n-0.003922\n" + values.astype("<f4").tobytes())
    out = read_pfm(path)
    np.testing.assert_array_equal(out, values)
    assert out.flags.writeable  # a one-row file must not come back as a read-only buffer view


def test_pfm_truncated_and_corrupt_raise(tmp_path):
    good = tmp_path / "g.pfm"
    write_pfm(good, np.ones((4, 5), np.float32))
    truncated = tmp_path / "t.pfm"
    truncated.write_bytes(good.read_bytes()[:-3])
    with pytest.raises(InputError, match="truncated"):
        read_pfm(truncated)
    bad_header = tmp_path / "h.pfm"
    bad_header.write_bytes(b"Pf\nfive 4\n-1\n" + bytes(80))
    with pytest.raises(InputError, match="corrupt header"):
        read_pfm(bad_header)
    zero_scale = tmp_path / "z.pfm"
    zero_scale.write_bytes(b"Pf\n1 1\n0\n" + bytes(4))
    with pytest.raises(InputError, match="byte"):
        read_pfm(zero_scale)
    colour = tmp_path / "c.pfm"
    colour.write_bytes(b"PF\n1 1\n-1\n" + bytes(12))
    with pytest.raises(InputError, match="colour"):
        read_pfm(colour)
    not_pfm = tmp_path / "n.pfm"
    not_pfm.write_bytes(b"P5\n1 1\n255\n\x00")
    with pytest.raises(InputError, match="not a grey PFM"):
        read_pfm(not_pfm)


def test_pfm_missing_file(tmp_path):
    with pytest.raises(InputError, match="not found"):
        read_pfm(tmp_path / "nope.pfm")


@needs_data
def test_read_pfm_on_middlebury_2014_motorcycle():
    scene = DATA / "middlebury2014_trainingQ" / "Motorcycle"
    gt = read_pfm(scene / "disp0GT.pfm")
    assert gt.shape == (497, 741)
    finite = gt[np.isfinite(gt)]
    assert round(float(finite.min()), 2) == 9.18
    assert round(float(finite.max()), 2) == 62.88
    mask = read_mask(scene / "mask0nocc.png")
    assert int(np.isinf(gt).sum()) == int((mask == 0).sum())
    assert np.array_equal(np.isinf(gt), mask == 0)


# ---------------------------------------------------------------- images


def test_read_image_rgb_order_grey_and_alpha(tmp_path):
    bgr = np.zeros((2, 3, 3), np.uint8)
    bgr[..., 0], bgr[..., 1], bgr[..., 2] = 10, 20, 30  # B, G, R
    _write_png_bgr(tmp_path / "c.png", bgr)
    rgb = read_image(tmp_path / "c.png")
    assert rgb.dtype == np.uint8 and rgb.shape == (2, 3, 3)
    assert tuple(rgb[0, 0]) == (30, 20, 10)

    bgra = np.dstack([bgr, np.full((2, 3), 7, np.uint8)])
    _write_png_bgr(tmp_path / "a.png", bgra)
    assert tuple(read_image(tmp_path / "a.png")[1, 2]) == (30, 20, 10)

    grey = np.arange(6, dtype=np.uint8).reshape(2, 3)
    _write_png_bgr(tmp_path / "g.png", grey)
    np.testing.assert_array_equal(read_image(tmp_path / "g.png"), grey)


def test_read_image_refuses_16_bit(tmp_path):
    _write_png_bgr(tmp_path / "w.png", np.full((2, 2), 1000, np.uint16))
    with pytest.raises(InputError, match="8-bit is needed"):
        read_image(tmp_path / "w.png")


def test_read_image_missing_and_corrupt(tmp_path):
    with pytest.raises(InputError, match=r"image file .*missing\.png not found"):
        read_image(tmp_path / "missing.png")
    garbage = tmp_path / "garbage.png"
    garbage.write_bytes(b"\x89PNG this is not really a png" * 10)
    with pytest.raises(InputError, match="garbage.png"):
        read_image(garbage)
    empty = tmp_path / "empty.png"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match="empty.png"):
        read_image(empty)
    good = tmp_path / "good.png"
    _write_png_bgr(good, np.full((40, 40, 3), 99, np.uint8))
    cut = tmp_path / "cut.png"
    cut.write_bytes(good.read_bytes()[:60])
    with pytest.raises(InputError, match="cut.png"):
        read_image(cut)


def test_to_grey_formula():
    rgb = np.array(
        [[[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255], [0, 0, 0], [10, 200, 37]]],
        dtype=np.uint8,
    )
    # (77 R + 150 G + 29 B + 128) >> 8, worked out by hand:
    # red 19763>>8 = 77; green 38378>>8 = 149; blue 7523>>8 = 29; white 65408>>8 = 255;
    # black 128>>8 = 0; (770 + 30000 + 1073 + 128) = 31971 >> 8 = 124.
    np.testing.assert_array_equal(to_grey(rgb), np.array([[77, 149, 29, 255, 0, 124]], np.uint8))
    grey = np.array([[3, 4]], np.uint8)
    np.testing.assert_array_equal(to_grey(grey), grey)
    np.testing.assert_array_equal(to_grey(grey[..., None]), grey)
    assert to_grey(rgb).dtype == np.uint8


def test_to_grey_rejects_wrong_dtype_and_channels():
    with pytest.raises(InputError, match=r"float32.*convert it to uint8"):
        to_grey(np.zeros((2, 2), np.float32))
    with pytest.raises(InputError, match=r"uint16.*convert it to uint8"):
        to_grey(np.zeros((2, 2, 3), np.uint16))
    with pytest.raises(InputError, match="4 channels"):
        to_grey(np.zeros((2, 2, 4), np.uint8))
    with pytest.raises(InputError, match="shape"):
        to_grey(np.zeros((2,), np.uint8))


# ---------------------------------------------------------------- writing


def test_png_is_deterministic_and_round_trips(tmp_path):
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (17, 23, 3), dtype=np.uint8)
    assert encode_png(img) == encode_png(img.copy())
    path = tmp_path / "i.png"
    path.write_bytes(encode_png(img))
    np.testing.assert_array_equal(read_image(path), img)


def test_disparity_colour_map(tmp_path):
    disp = np.array([[0.0, 32.0, 64.0, np.nan, np.inf, 100.0, -3.0]], np.float32)
    rgb = disparity_to_colour(disp, 64)
    assert rgb.dtype == np.uint8 and rgb.shape == (1, 7, 3)
    assert not rgb[0, 3].any() and not rgb[0, 4].any()
    turbo = cv2.applyColorMap(np.array([[0, 128, 255]], np.uint8), cv2.COLORMAP_TURBO)[0, :, ::-1]
    np.testing.assert_array_equal(rgb[0, :3], turbo)  # 32/64*255 = 127.5 rounds up to 128
    np.testing.assert_array_equal(rgb[0, 5], turbo[2])  # clipped at dmax
    np.testing.assert_array_equal(rgb[0, 6], turbo[0])  # clipped at 0
    with pytest.raises(InputError, match="dmax"):
        disparity_to_colour(disp, 0)

    a, b = tmp_path / "a.png", tmp_path / "b.png"
    write_disparity_png(a, disp, 64)
    write_disparity_png(b, disp.copy(), 64)
    assert a.read_bytes() == b.read_bytes()
    np.testing.assert_array_equal(read_image(a), rgb)


# ---------------------------------------------------------------- GT and masks


def test_read_gt_png_scale_and_unknown(tmp_path):
    raw = np.array([[0, 3, 255]], np.uint8)
    path = tmp_path / "disp1.png"
    _write_png_bgr(path, raw)
    gt = read_gt(path, scale=3)
    assert gt.dtype == np.float32
    assert np.isposinf(gt[0, 0])
    assert gt[0, 1] == 1.0 and gt[0, 2] == 85.0
    with pytest.raises(InputError, match="--gt-scale"):
        read_gt(path)

    raw16 = np.array([[0, 256 * 40 + 128]], np.uint16)
    _write_png_bgr(tmp_path / "k.png", raw16)
    gt16 = read_gt(tmp_path / "k.png", scale=256)
    assert np.isposinf(gt16[0, 0]) and gt16[0, 1] == 40.5


def test_read_gt_pfm_scale_and_extension(tmp_path):
    path = tmp_path / "g.pfm"
    write_pfm(path, np.array([[8.0, np.inf, np.nan]], np.float32))
    np.testing.assert_array_equal(read_gt(path), [[8.0, np.inf, np.inf]])
    np.testing.assert_array_equal(read_gt(path, scale=4), [[2.0, np.inf, np.inf]])
    with pytest.raises(InputError, match=r"\.pfm or \.png"):
        read_gt(tmp_path / "g.tif", scale=1)
    with pytest.raises(InputError, match="positive"):
        read_gt(path, scale=0)


def test_read_mask_and_missing(tmp_path):
    mask = np.array([[0, 128, 255]], np.uint8)
    _write_png_bgr(tmp_path / "m.png", mask)
    np.testing.assert_array_equal(read_mask(tmp_path / "m.png"), mask)
    with pytest.raises(InputError, match="not found"):
        read_mask(tmp_path / "none.png")


@needs_data
def test_read_mask_expands_palette_png():
    # nonocc.png of the 2003 data is a 1-bit palette PNG whose raw indices are 0/1.
    mask = read_mask(DATA / "middlebury2003_quarter" / "teddy" / "nonocc.png")
    assert mask.shape == (375, 450) and mask.dtype == np.uint8
    assert set(np.unique(mask).tolist()) == {0, 255}
