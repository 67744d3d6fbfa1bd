"""Outputs other tools read (sim.formats): KITTI PNG, OpenCV x16, depth in mm, PLY, calib.txt,
the MiddEval3 layout; and `stereosim run --save-as` / `stereosim eval --save`.

The expected values below are worked out by hand from the conventions in sim/formats.py."""

import hashlib
import io
import json
import math
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
from plyfile import PlyData

from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError, InputError
from stereosim.core.io import encode_png, pfm_bytes, read_pfm
from stereosim.sim import formats
from stereosim.sim.api import run
from stereosim.sim.cli import main
from stereosim.sim.cycle.estimate import estimate
from stereosim.sim.formats import Calibration

NAN, INF = float("nan"), float("inf")

# A 4x3 frame: exact binary fractions, NaN/inf/negative (invalid for KITTI and OpenCV), a value
# exactly half a KITTI step (1/512 px: rounds up to 1) and one too large for 16 bits (300 px).
DISP = np.array(
    [
        [0.0, 1.5, 2.25, NAN],
        [90.0, 255.75, INF, -1.0],
        [10.0, 1 / 512, 300.0, 40.0],
    ],
    dtype=np.float32,
)

# f = 1000 px, baseline 100 mm, doffs 10 px: Z = 100000 / (d + 10) mm.
CALIB = Calibration(
    fx_px=1000.0, fy_px=1000.0, cx_px=0.5, cy_px=0.5, doffs_px=10.0, baseline_mm=100.0
)

# The format of a MiddEval3 calib.txt, with made-up numbers.
CALIB_TEXT = """cam0=[1000 0 200.5; 0 1000 150.25; 0 0 1]
cam1=[1000 0 210.5; 0 1000 150.25; 0 0 1]
doffs=10
baseline=100
width=400
height=300
ndisp=64
isint=0
vmin=5
vmax=60
dyavg=0.1
dymax=0.2
"""


# ---------------------------------------------------------------- disparity encodings


def test_kitti_png_decodes_to_hand_computed_uint16():
    expected = np.array(
        [
            [0, 384, 576, 0],  # 0 px is 0 = invalid in KITTI; 1.5*256; 2.25*256; NaN
            [23040, 65472, 0, 0],  # 90*256; 255.75*256; inf; negative
            [2560, 1, 65535, 10240],  # 10*256; 0.5 rounds up; 76800 clipped; 40*256
        ],
        dtype=np.uint16,
    )
    np.testing.assert_array_equal(formats.kitti_u16(DISP), expected)
    png = formats.kitti_png_bytes(DISP)
    decoded = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED)
    assert decoded.dtype == np.uint16
    np.testing.assert_array_equal(decoded, expected)
    assert formats.kitti_png_bytes(DISP.copy()) == png  # deterministic bytes


def test_opencv16_is_exact_with_minus_16_for_invalid():
    expected = np.array(
        [
            [0, 24, 36, -16],
            [1440, 4092, -16, -16],
            [160, 0, 4800, 640],  # 1/512 * 16 = 0.03125 rounds to 0
        ],
        dtype=np.int16,
    )
    got = formats.opencv16_i16(DISP)
    assert got.dtype == np.int16
    np.testing.assert_array_equal(got, expected)
    loaded = np.load(io.BytesIO(formats.npy_bytes(got)), allow_pickle=False)
    assert loaded.dtype == np.int16
    np.testing.assert_array_equal(loaded, expected)
    # another minDisparity moves the invalid marker: (2 - 1) * 16, and 1.5 < 2 is invalid
    assert formats.opencv16_i16(np.array([[1.5, 2.0]], np.float32), 2).tolist() == [[16, 32]]


def test_opencv16_rounds_half_up():
    got = formats.opencv16_i16(np.array([[1 / 32, 3 / 32, 2047.96875]], np.float32))
    assert got.tolist() == [[1, 2, 32767]]


def test_converters_refuse_what_is_not_a_disparity_map():
    with pytest.raises(InputError, match="2-D float"):
        formats.kitti_u16(np.zeros((2, 2), np.uint8))
    with pytest.raises(InputError, match="2-D float"):
        formats.opencv16_i16(np.zeros(3, np.float32))


# ---------------------------------------------------------------- depth and points


def test_depth_in_millimetres_from_round_numbers():
    z = formats.depth_mm(DISP, CALIB)
    assert z[1, 0] == 1000.0  # 100 * 1000 / (90 + 10)
    assert z[2, 3] == 2000.0
    assert z[2, 0] == 5000.0
    assert z[0, 0] == 10000.0  # d = 0 is a real, distant point: 100000 / doffs
    assert math.isnan(z[0, 3]) and math.isnan(z[1, 2])
    expected = np.array(
        [
            [10000, 8696, 8163, 0],  # 100000/11.5 = 8695.65; 100000/12.25 = 8163.27
            [1000, 376, 0, 11111],  # 100000/265.75 = 376.29; -1 px: 100000/9 = 11111.1
            [5000, 9998, 323, 2000],  # 100000/10.00195 = 9998.05; 100000/310 = 322.58
        ],
        dtype=np.uint16,
    )
    depth = formats.depth_png_u16(DISP, CALIB)
    np.testing.assert_array_equal(depth, expected)
    png = encode_png(depth)
    np.testing.assert_array_equal(
        cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED), expected
    )


def test_depth_beyond_16_bits_or_infinity_is_invalid():
    # -8.5 px: 100000 / 1.5 = 66667 mm does not fit; -10 px: at infinity; -11 px: behind
    d = np.array([[-8.5, -10.0, -11.0, -5.0]], np.float32)
    assert formats.depth_png_u16(d, CALIB).tolist() == [[0, 0, 0, 20000]]
    assert np.isnan(formats.depth_mm(d, CALIB)[0, 1:3]).all()


def test_ply_vertices_read_back_exactly():
    disp = np.array([[90.0, NAN], [40.0, INF]], np.float32)
    left = np.array([[[10, 20, 30], [1, 2, 3]], [[40, 50, 60], [4, 5, 6]]], np.uint8)
    data = formats.ply_bytes(formats.point_cloud(disp, CALIB, left))
    assert data.startswith(b"ply\nformat binary_little_endian 1.0\n")
    assert formats.ply_bytes(formats.point_cloud(disp, CALIB, left.copy())) == data
    vertex = PlyData.read(io.BytesIO(data))["vertex"]
    assert [p.name for p in vertex.properties] == ["x", "y", "z", "red", "green", "blue"]
    # (x, y) = (0, 0): Z = 1000, X = (0 - 0.5) * 1000 / 1000, Y likewise;
    # (0, 1): Z = 2000, X = -0.5 * 2, Y = +0.5 * 2
    assert [tuple(v) for v in vertex.data] == [
        (-0.5, -0.5, 1000.0, 10, 20, 30),
        (-1.0, 1.0, 2000.0, 40, 50, 60),
    ]


def test_ply_of_a_grey_image_has_grey_vertices_and_only_valid_pixels():
    grey = np.arange(12, dtype=np.uint8).reshape(3, 4)
    points = formats.point_cloud(DISP, CALIB, grey)
    vertex = PlyData.read(io.BytesIO(formats.ply_bytes(points)))["vertex"].data
    valid = np.isfinite(formats.depth_mm(DISP, CALIB))
    assert len(vertex) == valid.sum() == 10
    np.testing.assert_array_equal(vertex["red"], grey[valid])
    np.testing.assert_array_equal(vertex["green"], vertex["blue"])
    np.testing.assert_array_equal(vertex["red"], vertex["blue"])
    with pytest.raises(InputError, match="left image"):
        formats.point_cloud(DISP, CALIB, grey[:2])


# ---------------------------------------------------------------- calib.txt


def _calib(tmp_path, text):
    path = tmp_path / "calib.txt"
    path.write_text(text)
    return path


def test_calib_txt_is_parsed(tmp_path):
    assert formats.read_calibration(_calib(tmp_path, CALIB_TEXT)) == Calibration(
        fx_px=1000.0,
        fy_px=1000.0,
        cx_px=200.5,
        cy_px=150.25,
        doffs_px=10.0,
        baseline_mm=100.0,
        width=400,
        height=300,
    )


def test_doffs_comes_from_cam1_when_absent(tmp_path):
    text = CALIB_TEXT.replace("doffs=10\n", "").replace("210.5", "212.75")
    assert formats.read_calibration(_calib(tmp_path, text)).doffs_px == 12.25


@pytest.mark.parametrize(
    "text, message",
    [
        (CALIB_TEXT.replace("baseline=100\n", ""), "has no baseline"),
        ("doffs=1\nbaseline=2\n", "has no cam0"),
        (CALIB_TEXT.replace("doffs=10\n", "").replace("cam1=", "camX="), "has no doffs"),
        (
            CALIB_TEXT.replace("[1000 0 200.5; 0 1000 150.25; 0 0 1]", "[1 2; 3 4]"),
            "cam0 is not a 3x3",
        ),
        (CALIB_TEXT.replace("[1000 0 200.5;", "[1000 0 x;"), "cam0 is not a 3x3"),
        (CALIB_TEXT.replace("[1000 0 200.5; 0 1000", "[0 0 200.5; 0 1000"), "focal lengths"),
        (CALIB_TEXT.replace("baseline=100", "baseline=-5"), "baseline=-5 must be a positive"),
        (CALIB_TEXT.replace("baseline=100", "baseline=abc"), "baseline=abc must be a positive"),
        (CALIB_TEXT.replace("doffs=10", "doffs=ten"), "doffs=ten must be a number"),
        (CALIB_TEXT.replace("width=400", "width=4.5"), "width=4.5 must be a whole number"),
        (CALIB_TEXT + "garbage\n", "is not 'key=value'"),
    ],
)
def test_bad_calib_txt_is_one_line(tmp_path, text, message):
    with pytest.raises(InputError, match=re.escape(message)) as info:
        formats.read_calibration(_calib(tmp_path, text))
    assert "\n" not in str(info.value)


def test_missing_calib_txt_is_one_line(tmp_path):
    with pytest.raises(InputError, match="nope.txt") as info:
        formats.read_calibration(tmp_path / "nope.txt")
    assert "\n" not in str(info.value)


# ---------------------------------------------------------------- --save-as parsing


def test_save_request_orders_formats_and_names_files(tmp_path):
    req = formats.save_request("ply, kitti,kitti", str(_calib(tmp_path, CALIB_TEXT)), None)
    assert req.formats == ("kitti", "ply")
    assert req.planned(Path("o")) == [
        (Path("o/disparity_kitti.png"), "--save-as kitti"),
        (Path("o/points.ply"), "--save-as ply"),
    ]
    assert req.calibration.width == 400
    req.check_size((300, 400, 3))
    with pytest.raises(InputError, match="is for 400x300 images but the pair is 401x300"):
        req.check_size((300, 401))


@pytest.mark.parametrize(
    "save_as, calib, message",
    [
        (
            "kitti,png",
            None,
            "unknown --save-as format 'png': choose from kitti, opencv16, depth, ply",
        ),
        (" , ", None, "--save-as is empty"),
        ("depth", None, "--save-as depth needs the focal length, baseline and doffs: give --calib"),
        ("kitti", "calib.txt", "--calib is used by --save-as depth or ply"),
        (None, "calib.txt", "--calib is used by --save-as depth or ply"),
    ],
)
def test_save_request_errors(save_as, calib, message):
    with pytest.raises(ConfigError, match=re.escape(message)):
        formats.save_request(save_as, calib, None)


# ---------------------------------------------------------------- MiddEval3 pieces


def test_middeval3_time_is_the_chip_frame_time_in_cycle_mode():
    seconds, source = formats.runtime_seconds({"latency": {"frame_ms": 4.125,
                                                           "first_output_us": 1.0}}, 12.3)
    assert source == "chip" and seconds == pytest.approx(0.004125, rel=1e-12)
    assert formats.runtime_seconds({"mode": "functional"}, 12.345) == (0.012345, "estimate")
    assert formats.time_text(0.004125, "chip") == "0.004125\n"
    assert formats.time_text(2.0238713118e-05, "chip") == "0.0000202387\n"  # no exponent
    assert formats.time_text(0.012345678, "estimate") == "0.0123457\n"


def test_algo_name_must_be_a_plain_file_name_part():
    assert formats.check_algo_name("SGM_chip-2") == "SGM_chip-2"
    for bad in ("", "a/b", "x y", "n" * 41):
        with pytest.raises(ConfigError, match="--algo-name"):
            formats.check_algo_name(bad)


# ---------------------------------------------------------------- the CLI


def _pair(folder: Path, h=21, w=57, shift=4, names=("l.png", "r.png")):
    rng = np.random.default_rng(1)
    base = rng.integers(0, 256, (h, w + shift), dtype=np.uint8)
    folder.mkdir(parents=True, exist_ok=True)
    left, right = folder / names[0], folder / names[1]
    left.write_bytes(encode_png(base[:, :w].copy()))
    right.write_bytes(encode_png(base[:, shift:].copy()))
    return left, right


def _cli(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _run_pair(left, right, out, *extra):
    """``stereosim run`` of a pair in the functional model, D = 16, into ``out``."""
    return ["run", "--left", left, "--right", right, "--disparities", "16", "--mode",
            "functional", "--out", out, *extra]


def _small_calib(tmp_path, w=57, h=21):
    return _calib(
        tmp_path,
        f"cam0=[1000 0 28; 0 1000 10; 0 0 1]\ndoffs=10\nbaseline=100\n"
        f"width={w}\nheight={h}\nndisp=16\n",
    )


def test_run_save_as_writes_every_format_in_the_published_set(tmp_path, capsys):
    left, right = _pair(tmp_path)
    calib = _small_calib(tmp_path)
    out = tmp_path / "out"
    code, stdout, _ = _cli(_run_pair(left, right, out, "--calib", calib, "--save-as",
                                     "kitti,opencv16,depth,ply"), capsys)
    assert code == 0, stdout
    assert "wrote disparity_kitti.png, disparity_opencv16.npy, depth_mm.png, points.ply" in stdout
    disp = read_pfm(out / "disparity.pfm")
    cal = formats.read_calibration(calib)
    kitti = cv2.imread(str(out / "disparity_kitti.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(kitti, formats.kitti_u16(disp))
    finite = np.isfinite(disp)
    np.testing.assert_array_equal(kitti[finite] / 256, np.floor(disp[finite] * 256 + 0.5) / 256)
    np.testing.assert_array_equal(
        np.load(out / "disparity_opencv16.npy"), formats.opencv16_i16(disp)
    )
    depth = cv2.imread(str(out / "depth_mm.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(depth, formats.depth_png_u16(disp, cal))
    vertex = PlyData.read(str(out / "points.ply"))["vertex"].data
    assert len(vertex) == finite.sum() > 0
    np.testing.assert_allclose(vertex["z"], 100 * 1000 / (disp[finite] + 10), rtol=1e-6)
    files = json.loads((out / "report.json").read_text())["files"]
    for name in ("disparity_kitti.png", "disparity_opencv16.npy", "depth_mm.png", "points.ply"):
        assert files[name] == hashlib.sha256((out / name).read_bytes()).hexdigest()


def test_run_save_as_takes_the_scene_folders_calib_txt(tmp_path, capsys):
    scene = tmp_path / "Scene"
    _pair(scene, names=("im0.png", "im1.png"))
    (scene / "calib.txt").write_text(_small_calib(tmp_path).read_text())
    code, stdout, _ = _cli(
        [
            "run",
            scene,
            "--mode",
            "functional",
            "--out",
            tmp_path / "o",
            "--save-as",
            "depth",
            "--json",
        ],
        capsys,
    )
    assert code == 0
    assert json.loads(stdout)["config"]["sva"]["disparities"] == 16  # ndisp from calib.txt
    assert (tmp_path / "o" / "depth_mm.png").is_file()


@pytest.mark.parametrize(
    "extra, message",
    [
        (
            ["--save-as", "ply"],
            ("--save-as ply needs the focal length, baseline and doffs: give --calib FILE"),
        ),
        (
            ["--save-as", "tiff"],
            ("unknown --save-as format 'tiff': choose from kitti, opencv16, depth, ply"),
        ),
        (["--save-as", "depth", "--calib", "WRONG"], "is for 40x21 images but the pair is 57x21"),
        (["--save-as", "kitti", "--frames", "2"], "--save-as writes one frame's files"),
    ],
)
def test_run_save_as_mistakes_are_one_line_and_write_nothing(tmp_path, capsys, extra, message):
    left, right = _pair(tmp_path)
    wrong = _small_calib(tmp_path, w=40)
    extra = [str(wrong) if a == "WRONG" else a for a in extra]
    out = tmp_path / "out"
    code, stdout, err = _cli(_run_pair(left, right, out, *extra), capsys)
    assert code == 2 and stdout == ""
    assert err.startswith("stereosim: error: ") and message in err and err.count("\n") == 1
    assert not out.exists()


def _dataset(tmp_path):
    """Two 2014-layout scenes with a constant GT and a third without GT (which fails)."""
    root = tmp_path / "ds"
    for name in ("Alpha", "Beta", "NoGT"):
        _pair(root / name, h=20, w=48, names=("im0.png", "im1.png"))
    for name in ("Alpha", "Beta"):
        (root / name / "disp0GT.pfm").write_bytes(pfm_bytes(np.full((20, 48), 4.0, np.float32)))
    return root


@pytest.mark.parametrize("mode", ["functional", "cycle"])
def test_eval_save_writes_the_middeval3_layout(tmp_path, capsys, mode):
    root = _dataset(tmp_path)
    save = tmp_path / "results"
    code, stdout, err = _cli(
        [
            "eval",
            root,
            "--disparities",
            "16",
            "--mode",
            mode,
            "--save",
            save,
            "--algo-name",
            "Chip",
        ],
        capsys,
    )
    assert code == 2 and "1 of 3 scenes failed" in err  # NoGT: scored scenes still saved
    assert sorted(p.relative_to(save).as_posix() for p in save.rglob("*")) == [
        "Alpha",
        "Alpha/disp0Chip.pfm",
        "Alpha/timeChip.txt",
        "Beta",
        "Beta/disp0Chip.pfm",
        "Beta/timeChip.txt",
    ]
    cfg = load_config(None, {"sva.disparities": 16})
    for scene in ("Alpha", "Beta"):
        left = cv2.imread(str(root / scene / "im0.png"), cv2.IMREAD_GRAYSCALE)
        right = cv2.imread(str(root / scene / "im1.png"), cv2.IMREAD_GRAYSCALE)
        res = run(left, right, mode=mode, config=cfg)
        np.testing.assert_array_equal(read_pfm(save / scene / "disp0Chip.pfm"), res.disparity)
        text = (save / scene / "timeChip.txt").read_text()
        if mode == "cycle":  # the simulated chip's frame time, which does not vary
            seconds = res.report["latency"]["frame_ms"] * 1e-3
            assert re.fullmatch(r"0\.0*[1-9]\d{0,5}\n", text)  # 6 digits, no exponent
            assert float(text) == pytest.approx(seconds, rel=1e-5)
        else:  # the analytic estimate's frame time: the same in every run
            seconds = estimate(cfg, left.shape)["latency"]["frame_ms"] * 1e-3
            assert float(text) == pytest.approx(seconds, rel=1e-5)
    what = ("simulated chip's frame time" if mode == "cycle"
            else "chip's frame time as the analytic estimate gives it")
    assert f"wrote disp0Chip.pfm and timeChip.txt (the {what}) for 2 scene(s) into" in stdout


def test_eval_save_refuses_a_bad_name_before_any_scene(tmp_path, capsys):
    root = _dataset(tmp_path)
    code, stdout, err = _cli(["eval", root, "--save", tmp_path / "r", "--algo-name", "a/b"], capsys)
    assert code == 2 and stdout == "" and "--algo-name 'a/b' must be" in err
    assert not (tmp_path / "r").exists()


def test_eval_refuses_an_algo_name_without_save(tmp_path, capsys):
    root = _dataset(tmp_path)
    code, stdout, err = _cli(["eval", root, "--algo-name", "Chip"], capsys)
    assert code == 2 and stdout == ""
    assert err.strip() == ("stereosim: error: --algo-name names the files of --save: give "
                           "--save DIR too")
