"""Config files layered (``--config A --config B``: a later file's keys win, each replaced key
noted), file-naming keys relative to their config file, and a chip built for its camera's
frame size."""

import json
import shutil

import numpy as np
import pytest

from stereosim.core.config import keys_set, layer_notes, load_config
from stereosim.core.errors import ConfigError, InputError
from stereosim.core.io import encode_png
from stereosim.nna.conv.weights import SHIPPED_WEIGHTS
from stereosim.sim.cli import PRESETS, main
from stereosim.sim.cycle.plan import DEFAULT_FRAME, build_plan, frame_size


def _write(path, text):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def test_later_files_win_key_by_key_and_every_replaced_key_is_noted(tmp_path):
    a = _write(tmp_path / "a.toml", "[sva]\np1 = 11\np2 = 300\n[nna]\nstereo_submodules = 4\n")
    b = _write(tmp_path / "b.toml", "[sva]\np1 = 12\n[clocks]\nsva_mhz = 400.0\n")
    cfg = load_config([a, b])
    assert (cfg.sva.p1, cfg.sva.p2, cfg.nna.stereo_submodules, cfg.clocks.sva_mhz) == (
        12, 300, 4, 400.0)  # b's p1, a's p2 and submodules, b's clock
    assert load_config([b, a]).sva.p1 == 11  # the order is the rule
    (note,) = layer_notes([a, b])
    assert note == "b.toml replaces 1 key of a.toml: sva.p1 11 -> 12"
    assert layer_notes([a, a]) == []  # the same value again replaces nothing
    assert keys_set([a, b]) >= {"sva.p1", "sva.p2", "clocks.sva_mhz", "nna.stereo_submodules"}
    assert load_config([a, b], {"sva.p1": 13}).sva.p1 == 13  # --set after every file


def test_two_presets_compose_on_the_command_line(capsys):
    """The robust network's preset under the 1080p60 preset: the robust network and its back
    end, the 1080p camera, the later preset's submodules -- and a note naming what 1080p60
    replaced."""
    assert main(["estimate", "--json", "--config", "robust-720p", "--config", "1080p60"]) == 0
    out, err = capsys.readouterr()
    est = json.loads(out)
    robust = load_config(PRESETS / "robust-720p.toml")
    assert est["image"] == {"width": 1920, "height": 1080}  # the camera's size, no --size
    assert est["config"]["nna"]["cnn"]["weights"] == robust.nna.cnn.weights
    assert est["config"]["sva"]["p1"] == robust.sva.p1
    assert est["config"]["nna"]["stereo_submodules"] == 6
    (line,) = err.splitlines()
    assert line.startswith("stereosim: note: 1080p60.toml replaces ") and "robust-720p.toml" in line
    assert "nna.stereo_submodules 10 -> 6" in line


def test_a_config_file_names_files_relative_to_itself_not_the_working_directory(
        tmp_path, monkeypatch):
    """nna.cnn.weights = "w.npz" in conf/c.toml is conf/w.npz from any folder; the working
    directory's own w.npz (a different network) does not shadow it; --set stays relative to
    the working directory."""
    conf = tmp_path / "conf"
    c = _write(conf / "c.toml", '[nna]\ndescriptor = "cnn"\n[nna.cnn]\nweights = "w.npz"\n'
               '[sva]\ndisparities = 16\n')
    shutil.copy(SHIPPED_WEIGHTS, conf / "w.npz")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "w.npz").write_bytes(b"not a weight file")
    monkeypatch.chdir(elsewhere)
    cfg = load_config(c)
    assert cfg.nna.cnn.weights == str(conf / "w.npz")
    build_plan(cfg, (24, 64))  # the config's file is read: a valid network
    with pytest.raises(ConfigError, match="w.npz"):  # --set: the working directory's file
        build_plan(load_config(c, {"nna.cnn.weights": "w.npz"}), (24, 64))


def test_a_lent_network_in_a_config_file_is_relative_to_it(tmp_path, monkeypatch):
    src = PRESETS / "lent" / "backbone224.toml"
    conf = tmp_path / "conf"
    shutil.copy(src, _write(conf / "net.toml", "").parent / "net.toml")
    c = _write(conf / "c.toml", '[nna]\nlent_submodules = 4\nlent_network = "net.toml"\n')
    monkeypatch.chdir(tmp_path)
    assert load_config(c).nna.lent_network == str(conf / "net.toml")


def test_a_chip_built_for_its_camera_takes_frames_of_that_size_only():
    cfg = load_config(PRESETS / "1080p60.toml")
    assert frame_size(cfg) == (1080, 1920)
    assert frame_size(load_config()) == DEFAULT_FRAME
    with pytest.raises(InputError) as err:
        build_plan(cfg, (720, 1280))
    assert "1280x720" in str(err.value) and "1920x1080" in str(err.value)
    assert "source.camera_width=0" in str(err.value)
    cleared = load_config(PRESETS / "1080p60.toml", {"source.camera_width": 0,
                                                     "source.camera_height": 0})
    build_plan(cleared, (720, 1280))  # the user chose to build it for these frames


def test_half_a_camera_size_is_refused():
    with pytest.raises(ConfigError, match="give both"):
        load_config(overrides={"source.camera_width": 1920})


def test_run_and_estimate_refuse_a_pair_of_another_size_in_one_line(tmp_path, capsys):
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (36, 80), dtype=np.uint8)
    left, right = tmp_path / "l.png", tmp_path / "r.png"
    left.write_bytes(encode_png(img))
    right.write_bytes(encode_png(img))
    out = tmp_path / "out"
    assert main(["run", "--config", "paper-720p", "--left", str(left), "--right", str(right),
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "80x36" in err and "1280x720" in err
    assert not out.exists()
    assert main(["estimate", "--config", "1080p60", "--size", "1280x720"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "1920x1080" in err


def test_config_plan_is_for_the_cameras_size_and_quotes_the_chips_energy_and_power(capsys):
    from stereosim.sim.cycle.estimate import estimate
    from stereosim.sim.summary import energy_lines

    assert main(["config", "plan", "--config", "1080p60"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("chip plan: 1920x1080")
    cfg = load_config(PRESETS / "1080p60.toml")
    (line,) = energy_lines(estimate(cfg, (1080, 1920))["energy"])
    assert line in out.splitlines() and " W at " in line


def test_estimate_prices_with_the_energy_table_given(tmp_path, capsys):
    from stereosim.sim.cycle.plan import DEFAULT_FRAME

    source = (PRESETS.parent / "sim" / "energy.toml").read_text()
    table = tmp_path / "e.toml"
    table.write_text(source.replace("node = ", 'node = "a test node" #', 1))
    assert main(["estimate", "--json", "--energy", str(table)]) == 0
    got = json.loads(capsys.readouterr().out)["energy"]
    assert got["table"]["node"] == "a test node"
    from stereosim.sim.cycle.energy import energy_table
    from stereosim.sim.cycle.estimate import estimate

    assert got == estimate(load_config(), DEFAULT_FRAME, energy_table(table))["energy"]
    assert main(["estimate", "--energy", str(tmp_path / "missing.toml")]) == 2
    assert capsys.readouterr().err.count("\n") == 1
