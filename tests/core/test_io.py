import errno
import io
import os
import struct
import tracemalloc
import zipfile
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from stereosim.core import npz as sim_npz
from stereosim.core.datasets import shared_data_dir
from stereosim.core.errors import ConfigError, InputError
from stereosim.core.io import (
    disparity_to_colour,
    encode_png,
    read_gt,
    read_image,
    read_mask,
    read_pfm,
    read_text,
    to_grey,
    write_disparity_png,
    write_pfm,
)
from stereosim.core.npz import NpzArrays, open_npz

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


def test_to_grey_is_the_formula_for_every_colour():
    """All 2^24 RGB triples, 16 values of R at a time (a 4096 x 256 image), against the
    formula in int32."""
    gb = np.arange(1 << 16, dtype=np.int32)
    g, b = gb >> 8, gb & 255
    for r0 in range(0, 256, 16):
        r = np.repeat(np.arange(r0, r0 + 16, dtype=np.int32), 1 << 16)
        gg, bb = np.tile(g, 16), np.tile(b, 16)
        rgb = np.stack([r, gg, bb], axis=-1).astype(np.uint8).reshape(4096, 256, 3)
        spec = ((77 * r + 150 * gg + 29 * bb + 128) >> 8).astype(np.uint8).reshape(4096, 256)
        np.testing.assert_array_equal(to_grey(rgb), spec)


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
    # 30 columns wide, so that 85 px is a disparity a scene of this width can have (<= 4 W).
    raw = np.zeros((1, 30), np.uint8)
    raw[0, 1:3] = 3, 255
    path = tmp_path / "disp1.png"
    _write_png_bgr(path, raw)
    gt = read_gt(path, scale=3)
    assert gt.dtype == np.float32
    assert np.isposinf(gt[0, 0])
    assert gt[0, 1] == 1.0 and gt[0, 2] == 85.0
    with pytest.raises(InputError, match="--gt-scale"):
        read_gt(path)

    raw16 = np.zeros((1, 16), np.uint16)
    raw16[0, 1] = 256 * 40 + 128
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


# ---------------------------------------------------------------- the pixel cap


def _png_header_only(path: Path, width: int, height: int) -> Path:
    """A PNG that is only its signature and a valid IHDR chunk (8-bit RGB, width x height)."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    chunk = struct.pack(">I", len(ihdr)) + b"IHDR" + ihdr
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr)))
    return path


def _jpeg_header_only(path: Path, width: int, height: int) -> Path:
    """SOI, a JFIF APP0 segment and a baseline frame header (SOF0) of width x height."""
    app0 = b"\xff\xe0" + struct.pack(">H", 16) + b"JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00"
    sof0 = b"\xff\xc0" + struct.pack(">HBHHB", 17, 8, height, width, 3)
    sof0 += b"\x01\x22\x00\x02\x11\x01\x03\x11\x01"
    path.write_bytes(b"\xff\xd8" + app0 + sof0 + b"\xff\xd9")
    return path


@pytest.fixture
def no_decoding(monkeypatch):
    """Fail the test if OpenCV is asked to decode: the header alone must be enough."""

    def refuse(*args, **kwargs):
        raise AssertionError("cv2.imdecode was called for an image the header already refuses")

    monkeypatch.setattr(cv2, "imdecode", refuse)


@pytest.mark.parametrize(
    ("read", "name", "what"),
    [
        (read_image, "big.png", "image"),
        (lambda p, **kw: read_gt(p, 1.0, **kw), "big.png", "GT"),
        (read_mask, "big.png", "mask"),
    ],
    ids=["image", "gt", "mask"],
)
def test_a_huge_png_is_refused_from_its_header(tmp_path, no_decoding, read, name, what):
    path = _png_header_only(tmp_path / name, 9000, 8000)
    assert path.stat().st_size < 100
    with pytest.raises(InputError) as info:
        read(path)
    assert str(info.value) == (
        f"{what} {path} is 9000x8000 (72.0 M pixels), above the 16.8 M-pixel cap: downsample it "
        "or raise the cap with --max-pixels"
    )


def test_a_huge_jpeg_is_refused_from_its_frame_header(tmp_path, no_decoding):
    path = _jpeg_header_only(tmp_path / "big.jpg", 9000, 8000)
    with pytest.raises(InputError, match=r"9000x8000 \(72.0 M pixels\), above the 16.8 M-pixel"):
        read_image(path)


def test_the_cap_reads_real_headers_and_can_be_raised(tmp_path, monkeypatch):
    rng = np.random.default_rng(1)
    img = rng.integers(0, 256, (30, 40, 3), dtype=np.uint8)
    png, jpg = tmp_path / "i.png", tmp_path / "i.jpg"
    png.write_bytes(encode_png(img))
    ok, buf = cv2.imencode(".jpg", img[:, :, ::-1])
    assert ok
    jpg.write_bytes(buf.tobytes())
    for path in (png, jpg):
        assert read_image(path, max_pixels=1200).shape == (30, 40, 3)  # exactly at the cap
    decode = cv2.imdecode
    with monkeypatch.context() as m:
        m.setattr(cv2, "imdecode", lambda *a: pytest.fail("decoded past the header"))
        for path in (png, jpg):
            with pytest.raises(InputError, match=r"40x30 \(0.0 M pixels\), above the 0.0 M-pixel"):
                read_image(path, max_pixels=1199)
    assert cv2.imdecode is decode
    # A header of a size above the default cap but under a raised one gets as far as decoding.
    big = _png_header_only(tmp_path / "big.png", 9000, 8000)
    with pytest.raises(InputError, match="corrupt"):
        read_image(big, max_pixels=10**8)


def test_other_formats_are_checked_after_decoding(tmp_path):
    ok, buf = cv2.imencode(".bmp", np.zeros((10, 10), np.uint8))
    assert ok
    path = tmp_path / "i.bmp"
    path.write_bytes(buf.tobytes())
    assert read_image(path).shape == (10, 10)
    with pytest.raises(InputError, match=r"10x10 .* above the 0.0 M-pixel cap"):
        read_image(path, max_pixels=99)


def test_a_pfm_is_refused_from_its_header_and_its_length(tmp_path):
    path = tmp_path / "big.pfm"
    path.write_bytes(b"Pf\n9000 8000\n-1\n" + bytes(16))
    with pytest.raises(InputError, match=r"9000x8000 \(72.0 M pixels\), above the 16.8 M-pixel"):
        read_pfm(path)
    with pytest.raises(InputError, match="9000x8000"):
        read_gt(path)
    small = tmp_path / "small.pfm"
    write_pfm(small, np.ones((4, 5), np.float32))
    assert read_pfm(small, max_pixels=20).shape == (4, 5)
    # 4 bytes a pixel and a header: a file longer than that is not read at all.
    long = tmp_path / "long.pfm"
    long.write_bytes(b"Pf\n1 1\n-1\n" + bytes(8000))
    with pytest.raises(InputError, match=r"long.pfm is 8010 bytes, more than the 4100 bytes"):
        read_pfm(long, max_pixels=1)


def test_an_image_file_longer_than_the_cap_allows_is_not_read(tmp_path):
    path = tmp_path / "long.png"
    path.write_bytes(encode_png(np.zeros((4, 4), np.uint8)) + bytes(16 << 20))
    with pytest.raises(InputError, match=r"long.png is 16.0 MiB, more than the 16.0 MiB allowed"):
        read_image(path, max_pixels=1)


# ---------------------------------------------------------------- decoder messages


def _damaged_files(tmp_path: Path) -> dict[str, Path]:
    img = np.random.default_rng(2).integers(0, 256, (40, 40, 3), dtype=np.uint8)
    png = encode_png(img)
    ok, buf = cv2.imencode(".jpg", img)
    assert ok
    jpg = buf.tobytes()
    bad_crc = bytearray(png)
    bad_crc[png.index(b"IDAT") + 10] ^= 0xFF
    files = {
        "truncated.png": png[: len(png) // 2],
        "bad-idat.png": bytes(bad_crc),
        "truncated.jpg": jpg[: len(jpg) // 2],
    }
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    return {name: tmp_path / name for name in files}


def test_corrupt_images_give_our_one_line_and_nothing_on_stderr(tmp_path, capfd):
    files = _damaged_files(tmp_path)
    # Not a vacuous check: OpenCV and libpng do print when they are not silenced.
    cv2.imdecode(np.frombuffer(files["bad-idat.png"].read_bytes(), np.uint8), cv2.IMREAD_COLOR)
    cv2.imdecode(np.frombuffer(files["truncated.png"].read_bytes(), np.uint8), cv2.IMREAD_COLOR)
    assert capfd.readouterr().err.strip()
    for name, path in files.items():
        for read in (read_image, read_mask):
            with pytest.raises(InputError, match="is corrupt or not an image format") as info:
                read(path)
            assert name in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(InputError, match="corrupt"):
        read_gt(files["bad-idat.png"], 1.0)
    assert capfd.readouterr().err == ""
    os.write(2, b"file descriptor 2 is back\n")
    assert capfd.readouterr().err == "file descriptor 2 is back\n"


def test_a_jpeg_libjpeg_warns_about_is_read_quietly(tmp_path, capfd):
    img = np.random.default_rng(3).integers(0, 256, (40, 40, 3), dtype=np.uint8)
    ok, buf = cv2.imencode(".jpg", img)
    assert ok
    jpg = buf.tobytes()
    # Junk bytes between two segments: libjpeg warns "Corrupt JPEG data: N extraneous bytes".
    dht = jpg.index(b"\xff\xc4")
    junk = jpg[:dht] + b"\x00" * 20 + jpg[dht:]
    cv2.imdecode(np.frombuffer(junk, np.uint8), cv2.IMREAD_COLOR)
    assert "Corrupt JPEG data" in capfd.readouterr().err
    path = tmp_path / "junk.jpg"
    path.write_bytes(junk)
    assert read_image(path).shape == (40, 40, 3)
    assert capfd.readouterr().err == ""


# ---------------------------------------------------------------- file-system errors

_READERS = {
    "image": (read_image, ".png"),
    "gt": (lambda p: read_gt(p, 1.0), ".pfm"),
    "gt-png": (lambda p: read_gt(p, 1.0), ".png"),
    "mask": (read_mask, ".png"),
    "pfm": (read_pfm, ".pfm"),
}


@pytest.mark.parametrize("reader", _READERS)
def test_a_folder_where_a_file_is_expected(tmp_path, reader):
    read, suffix = _READERS[reader]
    folder = tmp_path / f"folder{suffix}"
    folder.mkdir()
    with pytest.raises(InputError, match=r"is a folder: give the path of a file"):
        read(folder)


@pytest.mark.parametrize("reader", _READERS)
def test_a_path_too_long(tmp_path, reader):
    read, suffix = _READERS[reader]
    path = tmp_path / ("x" * 5000 + suffix)
    with pytest.raises(InputError, match=r"\(File name too long\): use a shorter path") as info:
        read(path)
    message = str(info.value)
    assert "\n" not in message and len(message) < 400 and "5" in message  # "(... characters)"


@pytest.mark.parametrize("reader", _READERS)
def test_permission_denied(tmp_path, monkeypatch, reader):
    read, suffix = _READERS[reader]
    path = tmp_path / f"locked{suffix}"
    path.write_bytes(b"anything")
    real_open = os.open

    def locked_open(name, *args, **kwargs):
        if os.fspath(name) == os.fspath(path):
            raise PermissionError(errno.EACCES, "Permission denied", os.fspath(name))
        return real_open(name, *args, **kwargs)

    monkeypatch.setattr(os, "open", locked_open)
    with pytest.raises(InputError) as info:
        read(path)
    assert str(info.value).endswith(f"file {path} (Permission denied): check its permissions")


def test_a_pipe_or_a_nul_byte_is_not_a_file(tmp_path):
    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="is not a regular file"):
        read_image(fifo)  # opened non-blocking: no writer needed, no hang
    with pytest.raises(InputError, match="not a valid path"):
        read_image(str(tmp_path / "a\0b.png"))
    with pytest.raises(InputError, match=r"line\\nbreak.png not found"):
        read_image(tmp_path / "line\nbreak.png")


def test_read_text_is_bounded_and_decoded(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text("# caf\u00e9\n[sva]\n", encoding="utf-8")
    assert read_text(path, "config", encoding="utf-8") == "# caf\u00e9\n[sva]\n"
    with pytest.raises(InputError, match=r"c.toml is not ascii text \(byte 5 is 0xc3"):
        read_text(path, "config")
    with pytest.raises(InputError, match=r"c.toml is 14 bytes, more than the 10 bytes allowed"):
        read_text(path, "config", max_bytes=10)
    with pytest.raises(InputError, match=r"config file .*none.toml not found: check the path"):
        read_text(tmp_path / "none.toml", "config")


# ---------------------------------------------------------------- impossible ground truth


def test_ground_truth_must_be_a_possible_disparity(tmp_path):
    width = 10
    path = tmp_path / "g.pfm"
    gt = np.full((2, width), 3.0, np.float32)
    gt[0, 0], gt[0, 1], gt[1, 2] = np.inf, -np.inf, 4 * width  # unknown, unknown, the largest
    write_pfm(path, gt)
    got = read_gt(path)
    assert np.isposinf(got[0, :2]).all() and got[1, 2] == 40.0
    gt[1, 3] = -0.5
    write_pfm(path, gt)
    with pytest.raises(InputError, match=r"negative disparity -0.5 at row 1, column 3"):
        read_gt(path)
    gt[1, 3] = 1e30
    write_pfm(path, gt)
    with pytest.raises(InputError, match=r"1e\+30 at row 1, column 3, more than 4 x its width 10"):
        read_gt(path)
    gt[1, 3] = 40.01
    write_pfm(path, gt)
    with pytest.raises(InputError, match="40.01"):
        read_gt(path)
    # A 16-bit PNG read with the wrong scale: 65535 / 1 on a 20-pixel-wide map.
    raw = np.full((2, 20), 65535, np.uint16)
    _write_png_bgr(tmp_path / "k.png", raw)
    with pytest.raises(InputError, match=r"65535 .*\(--gt-scale\)"):
        read_gt(tmp_path / "k.png", 1.0)
    assert read_gt(tmp_path / "k.png", 65535 / 80).max() == pytest.approx(80.0)


# ---------------------------------------------------------------- bounded .npz archives


def _npz(path: Path, members: dict[str, bytes], compression=zipfile.ZIP_STORED) -> Path:
    with zipfile.ZipFile(path, "w", compression) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return path


def _npy(arr: np.ndarray, **kwargs) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, arr, **kwargs)
    return buf.getvalue()


def _npy_header(shape: tuple, descr: str = "<f8", tail: bytes = bytes(16)) -> bytes:
    """An .npy header that claims ``shape``, followed by ``tail`` instead of the data."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buf, {"descr": descr, "fortran_order": False, "shape": shape}
    )
    return buf.getvalue() + tail


def _open(path) -> NpzArrays:
    return open_npz(str(path), "weight file", "write it with nna.save_weights")


def _peak_bytes(fn) -> int:
    """Peak Python/numpy allocation while ``fn`` runs (numpy reports its buffers to tracemalloc)."""
    tracemalloc.start()
    try:
        fn()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak


def _refused(path, match: str) -> str:
    with pytest.raises(ConfigError, match=match) as info:
        _open(path)
    message = str(info.value)
    assert "weight file " in message and f" '{path}' " in message and "\n" not in message
    return message


def test_npz_round_trip_stored_and_deflated(tmp_path):
    arrays = {
        "w": np.arange(12, dtype=np.int8).reshape(3, 4),
        "s": np.float64(0.5),
        "t": np.array("x"),
    }
    for save in (np.savez, np.savez_compressed):
        path = tmp_path / f"{save.__name__}.npz"
        save(path, **arrays)
        with _open(path) as got:
            assert got.files == ["w", "s", "t"]
            np.testing.assert_array_equal(got["w"], arrays["w"])
            assert got.scalar("s", "f") == 0.5 and got.scalar("t", "U") == "x"
            with pytest.raises(ConfigError, match=r"lacks the field 'nope'"):
                got.field("nope")
            with pytest.raises(ConfigError, match=r"w must be a scalar, got int8 \(3, 4\)"):
                got.scalar("w", "iu")


def test_npz_empty_single_array_and_not_a_zip(tmp_path):
    (tmp_path / "empty.npz").write_bytes(b"")
    _refused(tmp_path / "empty.npz", "is empty; write it with nna.save_weights$")
    np.save(tmp_path / "one.npy", np.zeros(3))
    _refused(tmp_path / "one.npy", "holds a single array, not an .npz archive")
    (tmp_path / "text.npz").write_bytes(b"PK but not really a zip file")
    _refused(tmp_path / "text.npz", "is not a readable .npz archive")
    (tmp_path / "cut.npz").write_bytes(b"PK\x03\x04 and then no zip at all")
    _refused(tmp_path / "cut.npz", "is not a readable .npz archive")


def test_npz_members_must_be_npy_arrays(tmp_path):
    _refused(_npz(tmp_path / "a.npz", {"notes.txt": b"hello"}), r"holds 'notes.txt', which is not")
    _refused(_npz(tmp_path / "b.npz", {"w.npy": b"hello, not an array"}), "not a readable .npz")
    objects = _npy(np.array([{"x": 1}], dtype=object), allow_pickle=True)
    _refused(_npz(tmp_path / "c.npz", {"w.npy": objects}), r"holds Python objects \(object\)")
    v3 = _npy(np.zeros(2), version=(3, 0))
    _refused(_npz(tmp_path / "d.npz", {"w.npy": v3}), r"format version 3.0 is not read here")
    twice = _npz(tmp_path / "e.npz", {"w.npy": _npy(np.zeros(2))})
    with zipfile.ZipFile(twice, "a") as archive, pytest.warns(UserWarning, match="Duplicate"):
        archive.writestr("w.npy", _npy(np.ones(2)))
    _refused(twice, "holds 'w.npy', which is not an .npy array of its own name")


def test_npz_header_claiming_ten_trillion_elements(tmp_path):
    path = _npz(tmp_path / "huge.npz", {"weights.npy": _npy_header((10**13,))})
    peak = _peak_bytes(lambda: _refused(path, r"claims \(10000000000000,\) float64 = 76293945"))
    assert peak < 4 << 20
    # The same lie in a member the zip directory says is large enough: the cap refuses it.
    fits = _npz(tmp_path / "fits.npz", {"w.npy": _npy_header((2, 3), tail=bytes(48))})
    assert _open(fits)["w"].shape == (2, 3)
    wrong = _npz(tmp_path / "wrong.npz", {"w.npy": _npy_header((2, 3), tail=bytes(40))})
    _refused(wrong, r"claims \(2, 3\) float64 = 48 bytes in its header, but .* gives it 40 bytes")


def test_npz_directory_claiming_1_5_gb_is_refused_before_unpacking(tmp_path):
    path = _npz(tmp_path / "bomb.npz", {"w.npy": _npy_header((375_000_000,), "<f4")})
    data = bytearray(path.read_bytes())
    central = data.index(b"PK\x01\x02")
    data[central + 24 : central + 28] = struct.pack("<I", 1_500_000_128)  # uncompressed size
    path.write_bytes(bytes(data))
    assert zipfile.ZipFile(path).infolist()[0].file_size == 1_500_000_128
    peak = _peak_bytes(
        lambda: _refused(path, r"of 1430.5 MiB unpacked, more than the 1024 members")
    )
    assert peak < 4 << 20


def test_npz_zip_bomb_by_ratio_and_by_size(tmp_path, monkeypatch):
    zeros = _npy(np.zeros(1 << 18))  # 2 MiB that deflates to about 2 KB
    bomb = _npz(tmp_path / "bomb.npz", {"w.npy": zeros}, zipfile.ZIP_DEFLATED)
    assert bomb.stat().st_size < 10_000
    _refused(bomb, r"unpacks \d+x \(2.0 MiB from \d+ bytes\), beyond the 100x of real arrays")
    # Under a lower cap (and no ratio limit), a deflated member larger than the cap is refused
    # from the directory, without inflating it.
    monkeypatch.setattr(sim_npz, "MAX_NPZ_BYTES", 1 << 20)
    monkeypatch.setattr(sim_npz, "MAX_NPZ_RATIO", 10**9)
    peak = _peak_bytes(lambda: _refused(bomb, r"2.0 MiB unpacked, more than .* 1.0 MiB allowed"))
    assert peak < 1 << 20
    monkeypatch.setattr(sim_npz, "MAX_NPZ_BYTES", 4 << 20)
    assert _open(bomb)["w"].shape == (1 << 18,)  # under the cap, the same file loads


def test_npz_file_system_errors_are_config_errors(tmp_path, monkeypatch):
    _refused(tmp_path / "none.npz", "not found: check the path")
    (tmp_path / "dir.npz").mkdir()
    _refused(tmp_path / "dir.npz", "is a folder: give the path of a file")
    long = tmp_path / ("x" * 5000 + ".npz")
    with pytest.raises(ConfigError, match=r"\(File name too long\): use a shorter path"):
        _open(long)
    locked = tmp_path / "locked.npz"
    np.savez(locked, w=np.zeros(2))
    real_open = os.open

    def locked_open(name, *args, **kwargs):
        if os.fspath(name) == str(locked):
            raise PermissionError(errno.EACCES, "Permission denied", str(name))
        return real_open(name, *args, **kwargs)

    monkeypatch.setattr(os, "open", locked_open)
    _refused(locked, r"\(Permission denied\): check its permissions")
