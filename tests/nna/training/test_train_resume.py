"""Long training runs (nna.trainrun): the thread count picked, checkpoints, and a resumed run
that ends with the same weights, bit for bit, as the run that was never stopped; a damaged or
crafted checkpoint is one line."""

import argparse
import io
from dataclasses import asdict, replace

import numpy as np
import pytest
import torch  # the test extra (train imports it)
from numpy.testing import assert_array_equal

import stereosim.nna.training.train as train_module
from stereosim.core.errors import ConfigError, InputError
from stereosim.nna.training.train import train
from stereosim.nna.training.trainconfig import TrainConfig
from stereosim.nna.training.traindata import training_scene_dirs
from stereosim.nna.training.trainrun import (
    checkpoint_path,
    load_checkpoint,
    parse_threads,
    pick_threads,
    threads_line,
)
from stereosim.sim.cli import main

SHIFT = 4


@pytest.fixture(scope="module")
def data_root(tmp_path_factory, scene_writer):
    root = tmp_path_factory.mktemp("data")
    scene_writer(root / "middlebury2006_third" / "Aloe", 3, SHIFT, h=24)
    scene_writer(root / "middlebury2005_third" / "Books", 2, SHIFT, h=24)
    return root


def test_the_default_thread_count_is_safe_on_small_machines():
    assert [pick_threads(0, cpus) for cpus in (1, 2, 3, 4, 6, 8, 16, 64)] == \
        [1, 1, 1, 2, 3, 4, 4, 4]
    assert pick_threads(3, 2) == 3  # an explicit count is kept
    assert threads_line(1, 0, 2) == \
        "training on 1 CPU thread (of 2, auto; --threads N to change)"
    assert threads_line(3, 3, 8) == \
        "training on 3 CPU threads (of 8, --threads; --threads N to change)"
    assert parse_threads("auto") == 0 and parse_threads("1") == 1
    for bad in ("0", "-1", "two", ""):
        with pytest.raises(argparse.ArgumentTypeError):
            parse_threads(bad)
    assert checkpoint_path("out/m.npz").as_posix() == "out/m.ckpt.pt"


class _Kill(KeyboardInterrupt):
    pass


def _interrupt_after(monkeypatch, name, steps):
    """Make the objective's step function raise (as a kill would) when step ``steps`` + 1
    starts, that is after ``steps`` completed steps."""
    real = getattr(train_module, name)
    calls = [0]

    def step(*args):
        calls[0] += 1
        if calls[0] > steps:
            raise _Kill
        return real(*args)

    monkeypatch.setattr(train_module, name, step)


@pytest.mark.parametrize("variant, objective, step_fn", [
    ("single9x9", "curve", "_curve_step"),
    ("mccnn4-slim", "triplet", "_triplet_step"),
])
def test_a_resumed_run_ends_with_the_weights_of_an_uninterrupted_one(
        data_root, tmp_path, monkeypatch, variant, objective, step_fn):
    cfg = TrainConfig(variant=variant, objective=objective, epochs=3, steps_per_epoch=4,
                      batch=16, strips=6, threads=1, seed=5)
    dirs = training_scene_dirs(data_root)
    straight = train(cfg, dirs, progress=False)
    ckpt = tmp_path / "m.ckpt.pt"
    with monkeypatch.context() as m:
        _interrupt_after(m, step_fn, 7)  # killed in step 8, of 12
        with pytest.raises(_Kill):
            train(cfg, dirs, progress=False, checkpoint=ckpt, checkpoint_every=3)
    saved = load_checkpoint(ckpt, straight["config"], straight["scenes"])
    assert saved["step"] == 6  # the last checkpoint before the kill
    assert len(saved["history"]) == 1  # epoch 1 done (steps 1-4), two steps into epoch 2
    resumed = train(cfg, dirs, progress=False, checkpoint=ckpt, checkpoint_every=3,
                    resume=True)
    for a, b in zip(straight["weights"] + straight["biases"],
                    resumed["weights"] + resumed["biases"]):
        assert_array_equal(a, b)
    assert resumed["loss_per_epoch"] == straight["loss_per_epoch"]
    assert resumed["config"] == straight["config"]
    # another seed really trains something else: the comparison above can fail
    other = train(TrainConfig(**{**straight["config"], "seed": 6}), dirs, progress=False)
    assert not np.array_equal(other["weights"][0], straight["weights"][0])


def test_a_checkpoint_of_other_settings_or_scenes_is_refused(data_root, tmp_path,
                                                            monkeypatch):
    cfg = TrainConfig(epochs=1, steps_per_epoch=4, strips=6, threads=1)
    dirs = training_scene_dirs(data_root)
    ckpt = tmp_path / "m.ckpt.pt"
    with monkeypatch.context() as m:
        _interrupt_after(m, "_curve_step", 2)
        with pytest.raises(_Kill):
            train(cfg, dirs, progress=False, checkpoint=ckpt, checkpoint_every=2)
    with pytest.raises(ConfigError, match=r"other settings: lr=0.004 \(now 0.001\)"):
        train(replace(cfg, lr=0.001), dirs, progress=False, checkpoint=ckpt, resume=True)
    with pytest.raises(ConfigError, match="other scenes"):
        train(cfg, dirs[:1], progress=False, checkpoint=ckpt, resume=True)
    # the device does not change the recipe: a GPU run may resume this CPU checkpoint (the
    # settings it compares are those of the run that wrote it, the device aside)
    scenes = torch.load(ckpt, weights_only=True)["scenes"]
    assert load_checkpoint(ckpt, {**asdict(cfg), "device": "cuda"}, scenes)["step"] == 2
    with pytest.raises(ConfigError, match="other settings: seed=0"):
        load_checkpoint(ckpt, {**asdict(cfg), "device": "cuda", "seed": 1}, scenes)
    # nor does the thread count: a resume may use another one
    assert train(replace(cfg, threads=2), dirs, progress=False, checkpoint=ckpt,
                 resume=True)["config"]["threads"] == 2
    ckpt.write_bytes(b"not a checkpoint")
    with pytest.raises(InputError, match="not a readable training checkpoint"):
        train(cfg, dirs, progress=False, checkpoint=ckpt, resume=True)


def _cli(data_root, out, *extra):
    return ["train", "--data", str(data_root), "--epochs", "2", "--steps", "3", "--strips",
            "6", "--threads", "1", "--out", str(out), "--quiet", *extra]


def test_the_train_command_checkpoints_and_resumes(data_root, tmp_path, monkeypatch, capsys):
    straight = tmp_path / "straight.npz"
    assert main([a for a in _cli(data_root, straight) if a != "--quiet"]) == 0
    assert "training on 1 CPU thread (of " in capsys.readouterr().err  # not with --quiet
    out = tmp_path / "m.npz"
    ckpt = tmp_path / "m.ckpt.pt"
    with monkeypatch.context() as m:
        _interrupt_after(m, "_curve_step", 5)
        assert main(_cli(data_root, out, "--checkpoint-every", "2")) == 130
    assert ckpt.is_file() and not out.exists()  # the kill keeps the last checkpoint
    capsys.readouterr()
    cases = [
        (_cli(data_root, out), "exists from an interrupted run: add --resume"),
        (_cli(data_root, out, "--resume", "--lr", "0.01"), "other settings: lr=0.004"),
        (_cli(data_root, tmp_path / "new.npz", "--resume"), "no checkpoint"),
        (_cli(data_root, out, "--threads", "0"), "'auto' or a whole number"),
    ]
    for args, message in cases:
        assert main(args) == 2
        err = capsys.readouterr().err
        assert err.startswith("stereosim: error: ") and message in err, err
        assert err.count("\n") == 1
    assert main(_cli(data_root, out, "--resume", "--checkpoint-every", "2")) == 0
    # the same file, byte for byte, as the run that was never stopped; the checkpoint is gone
    assert out.read_bytes() == straight.read_bytes()
    assert not ckpt.exists()


# ---------------------------------------------------------------- crafted checkpoints


@pytest.fixture(scope="module")
def interrupted(data_root, tmp_path_factory):
    """The checkpoint (step 2 of 4) of an interrupted run, with the run's settings."""
    cfg = TrainConfig(epochs=2, steps_per_epoch=2, strips=6, threads=1)
    ckpt = tmp_path_factory.mktemp("ckpt") / "m.ckpt.pt"
    with pytest.MonkeyPatch.context() as m:
        _interrupt_after(m, "_curve_step", 3)
        with pytest.raises(_Kill):
            train(cfg, training_scene_dirs(data_root), progress=False, checkpoint=ckpt,
                  checkpoint_every=2)
    return cfg, ckpt.read_bytes()


def _nan_weight(d):
    d["net"]["0.weight"][0, 0, 0, 0] = float("nan")


def _inf_moment(d):
    d["optimizer"]["state"][0]["exp_avg"][0] = float("inf")


CRAFTED = [
    (lambda d: d.pop("step"), "it lacks step"),
    (lambda d: d.pop("config"), "it lacks the settings and scenes of its run"),
    (lambda d: d.update(step=10**6), "its step 1000000 is not a step of this run"),
    (lambda d: d.update(step="2"), "its step '2' is not a step of this run"),
    (lambda d: d.update(history=[]), "its losses do not match its step"),
    (lambda d: d.update(running=float("nan")), "its losses do not match its step"),
    (_nan_weight, "net.0.weight holds NaN or infinite values (the run it saved had diverged)"),
    (_inf_moment, "optimizer.state.0.exp_avg holds NaN or infinite values"),
    (lambda d: d["net"].update({"0.weight": torch.zeros(1)}), "its net does not fit this run"),
    (lambda d: d["optimizer"]["param_groups"][0].update(lr="x"),
     "its optimizer state is not that of this run"),
    (lambda d: d["optimizer"].update(state={}), "its optimizer state is not that of this run"),
    (lambda d: d["schedule"].update(last_epoch=7), "its learning-rate schedule is not that"),
    (lambda d: d["schedule"].update(base_lrs=[1e30]), "its learning-rate schedule is not that"),
    (lambda d: d.update(numpy_rng={"bit_generator": "PCG64"}), "its numpy_rng does not fit"),
    (lambda d: d.update(torch_rng=torch.zeros(5, dtype=torch.uint8)),
     "its torch_rng does not fit"),
    (lambda d: d.update(log_temp=torch.zeros(3)), "its log_temp does not fit this run"),
]


@pytest.mark.parametrize("craft, message", CRAFTED)
def test_a_crafted_checkpoint_is_refused_with_one_line(interrupted, data_root, tmp_path, craft,
                                                        message):
    """`train --resume` trusted a checkpoint's contents: KeyError, RuntimeError, TypeError or
    IndexError tracebacks, and NaN weights resumed silently into a NaN model."""
    cfg, good = interrupted
    ckpt = tmp_path / "m.ckpt.pt"
    ckpt.write_bytes(good)
    data = torch.load(ckpt, weights_only=True)
    craft(data)
    torch.save(data, ckpt)
    with pytest.raises(InputError) as caught:
        train(cfg, training_scene_dirs(data_root), progress=False, checkpoint=ckpt, resume=True)
    line = str(caught.value)
    assert message in line and "\n" not in line and "delete it and run without --resume" in line
    ckpt.write_bytes(good)  # the untouched checkpoint resumes: the check refuses only the craft
    assert train(cfg, training_scene_dirs(data_root), progress=False, checkpoint=ckpt,
                 resume=True)["loss_per_epoch"]


def test_the_train_command_refuses_a_crafted_checkpoint_and_an_out_on_its_data(
        interrupted, data_root, tmp_path, capsys):
    _, good = interrupted
    ckpt = tmp_path / "m.ckpt.pt"
    data = torch.load(io.BytesIO(good), weights_only=True)
    _nan_weight(data)
    torch.save(data, ckpt)
    argv = ["train", "--data", str(data_root), "--epochs", "2", "--steps", "2", "--strips", "6",
            "--threads", "1", "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "m.npz"), "--resume"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds NaN or infinite values" in err
    view = data_root / "middlebury2005_third" / "Books" / "view1.png"
    before = view.read_bytes()
    assert main([*argv, "--out", str(view)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out path" in err and "is the input scene file" in err
    assert view.read_bytes() == before
