import errno
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from stereosim.core.datasets import (
    LAYOUT_2003,
    LAYOUT_2005,
    LAYOUT_2014,
    default_scene,
    find_scene,
    find_scenes,
    legal_disparities,
    load_scene,
    occluded_by_cross_check,
    parse_calib,
    shared_data_dir,
)
from stereosim.core.errors import InputError
from stereosim.core.io import read_gt, write_pfm

DATA = shared_data_dir()
needs_data = pytest.mark.skipif(
    DATA is None, reason="shared Middlebury data not found (set STEREOSIM_DATA or add ../shared)"
)


def _png(path: Path, arr: np.ndarray) -> None:
    ok, buf = cv2.imencode(".png", arr)
    assert ok
    path.write_bytes(buf.tobytes())


# ---------------------------------------------------------------- without the shared data


def test_parse_calib_numbers_and_matrices(tmp_path):
    calib = tmp_path / "calib.txt"
    calib.write_text(
        "cam0=[999.421 0 294.182; 0 999.421 252.932; 0 0 1]\ndoffs=32.778\nndisp = 70\n\nisint=0\n"
    )
    c = parse_calib(calib)
    assert c["cam0"] == "[999.421 0 294.182; 0 999.421 252.932; 0 0 1]"
    assert c["doffs"] == 32.778 and isinstance(c["doffs"], float)
    assert c["ndisp"] == 70 and isinstance(c["ndisp"], int)
    assert c["isint"] == 0
    calib.write_text("ndisp=70\nthis line is broken\n")
    with pytest.raises(InputError, match="line 2"):
        parse_calib(calib)
    with pytest.raises(InputError, match="not found"):
        parse_calib(tmp_path / "missing.txt")


@pytest.mark.parametrize(
    ("ndisp", "legal"), [(1, 16), (16, 16), (17, 32), (70, 80), (190, 192), (256, 256)]
)
def test_legal_disparities(ndisp, legal):
    assert legal_disparities(ndisp) == legal


@pytest.mark.parametrize("bad", [0, -5, 257, 2.5, True])
def test_legal_disparities_rejects(bad):
    with pytest.raises(InputError):
        legal_disparities(bad)


def test_cross_check_by_hand():
    inf = np.inf
    # One row, 6 px. Left pixel x with GT d maps to right x - d.
    left = np.array([[2.0, 2.0, 1.0, 1.0, inf, 0.0]])
    right = np.array([[1.0, 3.5, 1.0, inf, 9.0, 0.0]])
    occ = occluded_by_cross_check(left, right)
    # x=0: x'=-2 outside; x=1: x'=-1 outside; x=2: x'=1, right 3.5 vs 1 -> occluded;
    # x=3: x'=2, right 1.0 -> visible; x=4: unknown left GT -> never occluded;
    # x=5: x'=5, right 0.0 -> visible.
    np.testing.assert_array_equal(occ, [[True, True, True, False, False, False]])
    # x=0: x'=0 where the right GT is unknown -> occluded; x=1: x'=1, |2 - 0| > 1 -> occluded;
    # x=2: x'=1, |2 - 1| = 1 -> visible; x=3: x' = floor(3 - 1.5 + 0.5) = 2, |2 - 1.5| -> visible.
    occ2 = occluded_by_cross_check(
        np.array([[0.0, 0.0, 1.0, 1.5]]), np.array([[inf, 2.0, 2.0, 9.0]])
    )
    np.testing.assert_array_equal(occ2, [[True, True, False, False]])


def _scene_2014(folder: Path, ndisp: int = 40) -> None:
    folder.mkdir()
    img = np.zeros((4, 6, 3), np.uint8)
    _png(folder / "im0.png", img)
    _png(folder / "im1.png", img)
    gt = np.full((4, 6), 3.0, np.float32)
    gt[0, 0] = np.inf
    write_pfm(folder / "disp0GT.pfm", gt)
    mask = np.full((4, 6), 255, np.uint8)
    mask[0, 0] = 0
    mask[1, :2] = 128
    _png(folder / "mask0nocc.png", mask)
    (folder / "calib.txt").write_text(f"width=6\nheight=4\nndisp={ndisp}\n")


def test_find_and_load_synthetic_2014(tmp_path):
    _scene_2014(tmp_path / "Tiny")
    (tmp_path / "notes").mkdir()  # not a scene: skipped
    scenes = find_scenes(tmp_path)
    assert [s.name for s in scenes] == ["Tiny"]
    s = scenes[0]
    assert s.layout == LAYOUT_2014 and s.ndisp == 40 and s.gt_scale == 1.0
    loaded = load_scene(s)
    assert loaded["left"].shape == (4, 6, 3)
    assert np.isinf(loaded["gt"][0, 0]) and loaded["gt"][3, 5] == 3.0
    assert loaded["masks"]["all"].sum() == 23
    assert loaded["masks"]["nonocc"].sum() == 21
    # The scene folder itself is also a dataset of one scene.
    assert find_scenes(tmp_path / "Tiny")[0].name == "Tiny"


def test_a_folder_of_scenes_given_as_one_scene_points_to_eval(tmp_path):
    """``run`` on a dataset folder names its scenes and the two commands that fit."""
    for name in ("A", "B"):
        _scene_2014(tmp_path / name)
    with pytest.raises(InputError) as err:
        find_scene(tmp_path)
    text = str(err.value)
    assert "folder of 2 scenes (A, B)" in text
    assert f"stereosim run {tmp_path / 'A'}" in text and f"stereosim eval {tmp_path}" in text


def test_load_scene_rejects_mismatched_sizes(tmp_path):
    _scene_2014(tmp_path / "S")
    _png(tmp_path / "S" / "im1.png", np.zeros((4, 7, 3), np.uint8))
    with pytest.raises(InputError, match="same size"):
        load_scene(find_scene(tmp_path / "S"))


def test_unknown_layout_and_empty_dataset(tmp_path):
    (tmp_path / "left.png").write_bytes(b"")
    with pytest.raises(InputError, match="im0.png \\+ im1.png"):
        find_scene(tmp_path)
    with pytest.raises(InputError, match="no scene folders"):
        find_scenes(tmp_path)
    with pytest.raises(InputError, match="not found"):
        find_scenes(tmp_path / "nowhere")


def test_2005_layout_of_another_size_needs_explicit_scale(tmp_path):
    scene = tmp_path / "Half"
    scene.mkdir()
    img = np.zeros((2, 650), np.uint8)
    for name in ("view1.png", "view5.png", "disp1.png", "disp5.png"):
        _png(scene / name, img)
    with pytest.raises(InputError, match="--gt-scale"):
        find_scene(scene)
    assert find_scene(scene, gt_scale=2).gt_scale == 2.0


def test_load_scene_takes_the_pixel_cap(tmp_path):
    _scene_2014(tmp_path / "S")
    scene = find_scene(tmp_path / "S")
    assert load_scene(scene, max_pixels=24)["left"].shape == (4, 6, 3)
    with pytest.raises(InputError, match=r"im0.png is 6x4 .* above the 0.0 M-pixel cap"):
        load_scene(scene, max_pixels=23)


def test_scene_folders_with_impossible_ground_truth(tmp_path):
    _scene_2014(tmp_path / "S")
    gt = np.full((4, 6), 3.0, np.float32)
    gt[2, 1] = -1.0
    write_pfm(tmp_path / "S" / "disp0GT.pfm", gt)
    with pytest.raises(InputError, match=r"disp0GT.pfm holds the negative disparity -1"):
        load_scene(find_scene(tmp_path / "S"))


def test_scene_files_that_are_folders(tmp_path):
    _scene_2014(tmp_path / "S")
    (tmp_path / "S" / "mask0nocc.png").unlink()
    (tmp_path / "S" / "mask0nocc.png").mkdir()  # not a file: the scene has no mask
    assert find_scene(tmp_path / "S").mask is None
    (tmp_path / "S" / "calib.txt").unlink()
    (tmp_path / "S" / "calib.txt").mkdir()
    assert find_scene(tmp_path / "S").ndisp is None
    with pytest.raises(InputError, match="calib.txt is a folder: give the path of a file"):
        parse_calib(tmp_path / "S" / "calib.txt")
    (tmp_path / "S" / "im1.png").unlink()
    (tmp_path / "S" / "im1.png").mkdir()
    with pytest.raises(InputError, match="is not a scene folder"):
        find_scene(tmp_path / "S")


def test_scene_paths_too_long_or_unreadable(tmp_path, monkeypatch):
    long = tmp_path / ("s" * 5000)
    for find in (find_scene, find_scenes):
        with pytest.raises(InputError, match=r"\(File name too long\): use a shorter path"):
            find(long)
    with pytest.raises(InputError, match=r"File name too long"):
        parse_calib(long / "calib.txt")
    _scene_2014(tmp_path / "S")
    scene = find_scene(tmp_path / "S")
    locked = tmp_path / "S" / "disp0GT.pfm"
    real_stat, real_open, real_scandir = os.stat, os.open, os.scandir

    def denied(path):
        return PermissionError(errno.EACCES, "Permission denied", os.fspath(path))

    def stat(path, *args, **kwargs):
        if os.fspath(path) == str(locked):
            raise denied(path)
        return real_stat(path, *args, **kwargs)

    def open_(path, *args, **kwargs):
        if os.fspath(path) == str(locked):
            raise denied(path)
        return real_open(path, *args, **kwargs)

    def scandir(path):
        if os.fspath(path) == str(tmp_path):
            raise denied(path)
        return real_scandir(path)

    with monkeypatch.context() as m:
        m.setattr(os, "open", open_)
        with pytest.raises(InputError, match=r"disp0GT.pfm \(Permission denied\): check its"):
            load_scene(scene)
    with monkeypatch.context() as m:
        m.setattr(os, "stat", stat)
        with pytest.raises(InputError, match=r"GT .*disp0GT.pfm \(Permission denied\)"):
            find_scene(tmp_path / "S")
    with monkeypatch.context() as m:
        m.setattr(os, "scandir", scandir)
        with pytest.raises(InputError, match=r"cannot read dataset folder .* \(Permission denied"):
            find_scenes(tmp_path)


def test_calib_files_that_are_not_short_ascii_text(tmp_path):
    calib = tmp_path / "calib.txt"
    calib.write_bytes("ndisp=70\ncam0=\u00e9\n".encode())
    with pytest.raises(InputError, match=r"calib.txt is not ascii text \(byte 14 is 0xc3"):
        parse_calib(calib)
    calib.write_bytes(b"x" * ((1 << 20) + 1))
    with pytest.raises(InputError, match=r"is 1.0 MiB, more than the 1.0 MiB allowed"):
        parse_calib(calib)
    _scene_2014(tmp_path / "S")
    (tmp_path / "S" / "calib.txt").write_text("ndisp=many\n")
    with pytest.raises(InputError, match="has ndisp=many: it must be a whole number"):
        find_scene(tmp_path / "S")


def test_default_scene():
    s = default_scene()
    assert s["name"] == "Motorcycle (scikit-image)"
    assert s["left"].shape == (500, 741, 3) and s["left"].dtype == np.uint8
    assert s["right"].shape == (500, 741, 3)
    assert s["gt"].dtype == np.float32 and s["gt"].shape == (500, 741)
    assert not np.isnan(s["gt"]).any()
    assert list(s["masks"]) == ["all"]
    np.testing.assert_array_equal(s["masks"]["all"], np.isfinite(s["gt"]))
    assert 0.5 < s["masks"]["all"].mean() < 1.0
    assert "nonocc" in s["note"] or "occlusion" in s["note"]


# ---------------------------------------------------------------- on the shared data


@needs_data
@pytest.mark.parametrize(
    ("collection", "count", "layout"),
    [
        ("middlebury2014_trainingQ", 15, LAYOUT_2014),
        ("middlebury2005_third", 6, LAYOUT_2005),
        ("middlebury2006_third", 20, LAYOUT_2005),
        ("middlebury2003_quarter", 2, LAYOUT_2003),
    ],
)
def test_find_scenes_on_shared_data(collection, count, layout):
    scenes = find_scenes(DATA / collection)
    assert len(scenes) == count
    assert [s.name for s in scenes] == sorted(s.name for s in scenes)
    assert all(s.layout == layout and s.gt is not None for s in scenes)


@needs_data
def test_motorcycle_ndisp():
    scene = find_scene(DATA / "middlebury2014_trainingQ" / "Motorcycle")
    assert scene.ndisp == 70
    assert legal_disparities(scene.ndisp) == 80
    loaded = load_scene(scene)
    assert loaded["masks"]["nonocc"].sum() < loaded["masks"]["all"].sum()
    np.testing.assert_array_equal(loaded["masks"]["all"], np.isfinite(loaded["gt"]))


@needs_data
def test_2005_occlusion_mask():
    scene = find_scene(DATA / "middlebury2005_third" / "Art")
    assert scene.gt_scale == 3.0 and scene.gt_right is not None
    loaded = load_scene(scene)
    finite = np.isfinite(loaded["gt"])
    nonocc, every = loaded["masks"]["nonocc"], loaded["masks"]["all"]
    np.testing.assert_array_equal(every, finite)
    assert not (nonocc & ~finite).any()  # a subset of finite GT
    occluded = finite & ~nonocc
    assert occluded.any()  # and the occlusion mask is non-empty
    # Art's occluded region is mostly the strip at the left image border and object edges.
    assert 0.05 < occluded.mean() < 0.4
    assert round(float(loaded["gt"][finite].max()), 2) == 74.67


@needs_data
def test_cross_check_agrees_with_middlebury_2003_nonocc():
    # 2003 ships official nonocc masks; the cross-check used for 2005/2006 must reproduce them.
    for name in ("cones", "teddy"):
        scene = find_scene(DATA / "middlebury2003_quarter" / name)
        loaded = load_scene(scene)
        gt_right = read_gt(scene.gt_right, scene.gt_scale)
        derived = np.isfinite(loaded["gt"]) & ~occluded_by_cross_check(loaded["gt"], gt_right)
        agreement = (derived == loaded["masks"]["nonocc"]).mean()
        assert agreement > 0.98, (name, agreement)
