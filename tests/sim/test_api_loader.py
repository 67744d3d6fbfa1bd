"""What the top of the package offers a script: stereosim.load_scene (images, ground truth,
masks, calibration), stereosim.read_pfm / write_pfm, and run_stream's checks of what it is
given."""

import numpy as np
import pytest

import stereosim
from stereosim.core.datasets import find_scene, shared_data_dir
from stereosim.core.datasets import load_scene as read_scene
from stereosim.core.errors import InputError
from stereosim.core.io import encode_png


def _scene(folder, h=12, w=40, with_calib=True):
    rng = np.random.default_rng(1)
    folder.mkdir()
    for name in ("im0.png", "im1.png"):
        (folder / name).write_bytes(encode_png(rng.integers(0, 256, (h, w), dtype=np.uint8)))
    gt = np.full((h, w), 3.5, np.float32)
    gt[0, 0] = np.inf
    stereosim.write_pfm(folder / "disp0GT.pfm", gt)
    mask = np.full((h, w), 255, np.uint8)
    mask[1, 1] = 128
    (folder / "mask0nocc.png").write_bytes(encode_png(mask))
    if with_calib:
        (folder / "calib.txt").write_text(
            "cam0=[100 0 20; 0 100 6; 0 0 1]\ncam1=[100 0 22; 0 100 6; 0 0 1]\ndoffs=2\n"
            "baseline=150.5\nwidth=40\nheight=12\nndisp=31\n")
    return gt, mask


def test_load_scene_reads_a_scene_folder_as_the_cli_does(tmp_path):
    gt, mask = _scene(tmp_path / "S")
    got = stereosim.load_scene(tmp_path / "S")
    want = read_scene(find_scene(tmp_path / "S"))
    for key in ("left", "right", "gt"):
        np.testing.assert_array_equal(got[key], want[key])
    np.testing.assert_array_equal(got["gt"], gt)
    np.testing.assert_array_equal(got["masks"]["nonocc"], mask == 255)
    assert got["ndisp"] == 31 and got["name"] == "S"
    cal = got["calibration"]
    assert (cal.fx_px, cal.doffs_px, cal.baseline_mm) == (100.0, 2.0, 150.5)


def test_load_scene_without_calibration_and_the_default_scene(tmp_path):
    _scene(tmp_path / "S", with_calib=False)
    assert stereosim.load_scene(str(tmp_path / "S"))["calibration"] is None
    default = stereosim.load_scene("default")
    assert default["left"].shape[:2] == default["gt"].shape and default["calibration"] is None


def test_load_scene_refuses_what_is_not_a_scene_in_one_line(tmp_path):
    for bad in (tmp_path / "missing", 3):
        with pytest.raises(InputError) as err:
            stereosim.load_scene(bad)
        assert "\n" not in str(err.value)


def test_read_pfm_and_write_pfm_round_trip_at_the_top_of_the_package(tmp_path):
    disp = np.arange(12, dtype=np.float32).reshape(3, 4)
    disp[2, 3] = np.inf
    stereosim.write_pfm(tmp_path / "d.pfm", disp)
    np.testing.assert_array_equal(stereosim.read_pfm(tmp_path / "d.pfm"), disp)
    assert {"load_scene", "read_pfm", "write_pfm"} <= set(dir(stereosim))


@pytest.mark.skipif(shared_data_dir() is None, reason="needs ../shared/data (Middlebury scenes)")
def test_load_scene_reads_a_middlebury_2014_scene_with_its_calibration():
    folder = shared_data_dir() / "middlebury2014_trainingQ" / "Adirondack"
    data = stereosim.load_scene(folder)
    assert data["calibration"] is not None and data["calibration"].width == data["left"].shape[1]
    assert set(data["masks"]) == {"nonocc", "all"}


class _NegativeLength:
    def __len__(self):
        return -1

    def __getitem__(self, i):
        raise IndexError(i)


def test_run_stream_refuses_a_dict_a_string_and_a_broken_length_in_one_line():
    img = np.zeros((8, 40), np.uint8)
    for bad in ({0: (img, img)}, "ab", _NegativeLength()):
        with pytest.raises(InputError) as err:
            stereosim.run_stream(bad, overrides={"sva.disparities": 16})
        assert "\n" not in str(err.value) and "pairs" in str(err.value)
