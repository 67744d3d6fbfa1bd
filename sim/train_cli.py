"""The learned descriptor's subcommands of ``stereosim``: ``train`` and ``quantize``.

Registered by :func:`register` from :func:`sim.cli.build_parser`; errors follow the CLI's rule
(one line, exit status 2, nothing half-written: the one output is checked before the work
starts and written atomically at the end).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from stereosim.core.datasets import scene_files, shared_data_dir
from stereosim.core.errors import ConfigError, InputError, UserError
from stereosim.core.outputs import check_outputs
from stereosim.nna.training.augment import RECIPES
from stereosim.nna.training.floatmodel import load_float_model, save_float_model
from stereosim.nna.training.train import train
from stereosim.nna.training.trainconfig import DEVICES, VARIANTS, TrainConfig
from stereosim.nna.training.traindata import (
    calibration_images,
    calibration_scene_dirs,
    leave_fold_out,
    training_scene_dirs,
)
from stereosim.nna.training.trainqat import build_qat_net, export_quantized
from stereosim.nna.training.trainrun import (
    box_width,
    check_checkpoint_option,
    checkpoint_path,
    parse_threads,
)
from stereosim.quant.artifact import save_quantized
from stereosim.quant.quantizer import FloatModel, QuantizerConfig, quantize, quantize_twin
from stereosim.sim.argtypes import (
    check_single_output,
    finite_float,
    nonempty_path,
    nonnegative_int,
    positive_int,
)


def register(sub) -> None:
    """Add ``train`` and ``quantize`` to ``sub`` (the parser's subparsers)."""
    _add_train_parser(sub)
    _add_quantize_parser(sub)


def parse_fold(text: str) -> tuple[int, int]:
    """argparse type: ``K/N``, fold K (0-based) of N cross-validation folds."""
    fold, _, folds = text.partition("/")
    if not (fold.strip().isdigit() and folds.strip().isdigit()):
        raise argparse.ArgumentTypeError(f"{text!r} is not K/N (fold K of N, e.g. 0/5)")
    return int(fold), int(folds)


def _import_torch():
    try:
        import torch  # noqa: F401
    except ImportError:
        raise UserError(
            "training needs torch, which is not installed: pip install 'stereosim[train]'"
        ) from None


# what a QAT run keeps of its base model's training settings unless given again
QAT_KEPT = ("objective", "strips", "strip_width", "disparities", "box", "temperature", "balance",
            "decorrelate", "gain", "offset", "noise_max", "gamma", "shot_noise", "blur_max",
            "vshift_max", "input_offset", "input_scale")
QAT_EPOCHS, QAT_LR = 4, 0.0005


def cmd_train(args) -> int:
    if args.qat is not None:
        return _cmd_qat(args)
    # options left unset keep TrainConfig's defaults (the shipped recipe)
    given = {
        "variant": args.variant or "single9x9", "objective": args.objective, "epochs": args.epochs,
        "steps_per_epoch": args.steps, "batch": args.batch, "strips": args.strips,
        "lr": args.lr, "seed": args.seed, "similarity": args.similarity,
        "noise_max": args.noise_max, "blur_max": args.blur_max, "aggregate": args.aggregate,
        "box": args.box, "threads": args.threads, "device": args.device,
    }
    recipe = dict(RECIPES[args.augment])  # then the options given on their own win
    cfg = TrainConfig(**{**recipe, **{k: v for k, v in given.items() if v is not None}})
    out = Path(args.out or f"{cfg.variant}.npz")
    check_single_output(out, "--out")
    _, dirs = _training_dirs(args)
    ckpt = checkpoint_path(out) if args.checkpoint_every or args.resume else None
    check_outputs([(out, "--out"), *([(ckpt, "the checkpoint")] if ckpt else [])],
                  scene_files(dirs))
    if ckpt is not None:
        check_checkpoint_option(ckpt, args.resume)
    _import_torch()
    t0 = time.perf_counter()
    result = train(cfg, dirs, progress=not args.quiet, checkpoint=ckpt,
                   checkpoint_every=args.checkpoint_every, resume=args.resume, log=_note(args))
    save_float_model(out, result)
    if ckpt is not None:
        ckpt.unlink(missing_ok=True)  # the model is written: the checkpoint is spent
    print(
        f"trained {args.variant} on {len(result['scenes'])} scenes ({result['samples']} pixels) in "
        f"{time.perf_counter() - t0:.0f} s; final loss {result['loss_per_epoch'][-1]:.4f}; "
        f"wrote {out}"
    )
    return 0


def _note(args):
    """Where the notes of a run go (its thread count, the quantiser's agreement): stderr, or
    nowhere with ``--quiet``."""
    if args.quiet:
        return None
    return lambda line: print(line, file=sys.stderr)


def _training_dirs(args) -> tuple:
    """(the data folder, its training scenes): ``--data`` or the shared Middlebury folder, the
    scenes less ``--leave-out-fold``."""
    data = args.data or shared_data_dir()
    if data is None:
        raise InputError("no training data found: give --data DIR (the shared Middlebury folder)")
    dirs = training_scene_dirs(data)
    if args.leave_out_fold is not None:
        dirs = leave_fold_out(dirs, *args.leave_out_fold)
    return data, dirs


def _cmd_qat(args) -> int:
    """``train --qat BASE``: quantise BASE with the project's quantiser, fine-tune it through the
    frozen integer arithmetic (:mod:`nna.training.trainqat`), write the int8 artifact."""
    if args.out is None:
        raise InputError("--qat needs --out (the int8 artifact to write)")
    out = Path(args.out)
    check_single_output(out, "--out", [(args.qat, "--qat")])
    model, variant, training = load_float_model(args.qat)
    if args.variant is not None and args.variant != variant:
        raise InputError(f"--variant {args.variant} but {args.qat} is a {variant} model")
    base = _base_settings(training, args.qat)
    if args.objective not in (None, "curve") or base.get("objective") != "curve":
        raise InputError("--qat fine-tunes with the curve objective only")
    kept = {k: base[k] for k in QAT_KEPT if k in base}
    given = {"epochs": args.epochs, "steps_per_epoch": args.steps, "strips": args.strips,
             "lr": args.lr, "noise_max": args.noise_max, "blur_max": args.blur_max,
             "box": args.box}
    cfg = TrainConfig(**{
        **kept, "variant": variant, "seed": args.seed, "threads": args.threads,
        "device": args.device,
        "epochs": QAT_EPOCHS, "lr": QAT_LR, "qat": Path(args.qat).name,
        # the base run ended on the signs at its largest tanh scale: QAT stays there
        "scale_start": base["scale_end"], "scale_end": base["scale_end"], "sign_fraction": 1.0,
        **{k: v for k, v in given.items() if v is not None}})
    data, dirs = _training_dirs(args)
    ckpt = checkpoint_path(out) if args.checkpoint_every or args.resume else None
    float_out = Path(args.float_out) if args.float_out else None
    outputs = [(out, "--out"), *([(float_out, "--float-out")] if float_out else []),
               *([(ckpt, "the checkpoint")] if ckpt else [])]
    check_outputs(outputs, scene_files(dirs))
    if ckpt is not None:
        check_checkpoint_option(ckpt, args.resume)
    _import_torch()
    t0 = time.perf_counter()
    images, names = calibration_images(calibration_scene_dirs(data), 8)
    qcfg = QuantizerConfig()
    calibration = (f"{len(images)} views (left+right) of {', '.join(names)}; quantiser defaults "
                   f"(seed {qcfg.seed}, {qcfg.n_samples} samples, {qcfg.n_steps} steps, "
                   f"{_equalize_text(len(model.weights), qcfg.equalize)}); then "
                   f"QAT, {cfg.epochs} x {cfg.steps_per_epoch} batches, lr {cfg.lr}, seed "
                   f"{cfg.seed}, from {Path(args.qat).name}")
    # QAT trains the float model whose twin qm is (the equalised one by default)
    model, qm = quantize_twin(model, images, qcfg, variant=variant, calibration=calibration,
                              progress=not args.quiet)
    note = _note(args)
    if note is not None:
        note(f"quantiser: {100 * qm.sign_agreement:.3f}% of the calibration bits agree with "
             f"{Path(args.qat).name}'s float signs")
    result = train(cfg, dirs, progress=not args.quiet, checkpoint=ckpt,
                   checkpoint_every=args.checkpoint_every, resume=args.resume, log=note,
                   make_net=lambda: build_qat_net(model, qm))
    latent = FloatModel(weights=tuple(np.float64(w) for w in result["weights"]),
                        biases=tuple(np.float64(b) for b in result["biases"]),
                        input_offset=model.input_offset, input_scale=model.input_scale)
    qat = export_quantized(latent, qm, images, calibration)
    if float_out is not None:
        save_float_model(float_out, result)
    save_quantized(out, qat)
    if ckpt is not None:
        ckpt.unlink(missing_ok=True)
    print(f"QAT of {variant} on {len(result['scenes'])} scenes in {time.perf_counter() - t0:.0f} "
          f"s: {100 * qat.sign_agreement:.3f}% of the calibration bits agree with its float "
          f"signs (quantiser alone: {100 * qm.sign_agreement:.3f}%); wrote {out}")
    return 0


def _base_settings(training, source) -> dict:
    """The settings of the run that trained the ``--qat`` base model (its training record's
    ``config``), checked before any is used: a record of another shape, without the last tanh
    scale, or with a setting TrainConfig refuses (the rules every run's settings pass: ``box``
    in sva.box_size's range, ``disparities`` at most the chip's, whole numbers where whole
    numbers belong, ...) is one line naming the file."""
    where = f"float model {str(source)!r}: its training record"
    base = training.get("config") if isinstance(training, dict) else None
    if not isinstance(base, dict):
        raise ConfigError(f"{where} has no settings (a 'config' object): write the model with "
                          "'stereosim train'")
    if "scale_end" not in base:
        raise ConfigError(f"{where} lacks scale_end (the tanh scale QAT continues from)")
    settings = {f.name for f in dataclasses.fields(TrainConfig)}
    try:
        TrainConfig(**{k: v for k, v in base.items() if k in settings})
    except ConfigError as err:
        raise ConfigError(f"{where}: {err}") from None
    return base


def _equalize_text(n_layers: int, equalize: bool) -> str:
    """How the hidden channels' activation ranges were set, for the artifact's record."""
    if n_layers == 1:
        return "no hidden layer"
    return ("hidden channels equalised to one activation range" if equalize
            else "one activation range a layer (not equalised)")


def cmd_quantize(args) -> int:
    check_single_output(Path(args.out), "--out", [(args.model, "model")])
    model, variant, _ = load_float_model(args.model)
    qcfg = QuantizerConfig(
        n_steps=args.steps, z_bits=args.z_bits, n_samples=args.samples, seed=args.seed,
        distance=args.distance, hidden_distance=args.hidden_distance,
        act_quantile=args.act_quantile, equalize=args.equalize,
    )
    out = Path(args.out)
    dirs = calibration_scene_dirs(args.calib)
    check_outputs([(out, "--out")], scene_files(dirs))
    images, names = calibration_images(dirs, args.calib_scenes)
    calibration = (
        f"{len(images)} views (left+right) of {', '.join(names)}; {qcfg.n_samples} sampled "
        f"pixels, seed {qcfg.seed}, {qcfg.n_steps} scale steps, z={qcfg.z_bits}, "
        f"distance {qcfg.distance}"
        + (
            f", hidden layers: distance {qcfg.hidden_distance}, activation quantile "
            f"{qcfg.act_quantile}, {_equalize_text(len(model.weights), qcfg.equalize)}"
            if len(model.weights) > 1
            else ""
        )
    )
    t0 = time.perf_counter()
    qm = quantize(model, images, qcfg, variant=variant, calibration=calibration,
                  progress=not args.quiet)
    save_quantized(out, qm)
    print(
        f"quantized {variant} ({qm.n_layers} layer(s)) on {len(images)} calibration views in "
        f"{time.perf_counter() - t0:.0f} s: {100 * qm.sign_agreement:.3f}% of descriptor bits "
        f"agree with the float signs, accumulator RMS error {qm.acc_rms:.2f}; wrote {out}"
    )
    return 0


def _add_train_parser(sub) -> None:
    """``stereosim train``: the learned descriptor (needs torch)."""
    t = sub.add_parser("train", help="train a siamese descriptor network (needs torch)")
    t.add_argument("--variant", choices=tuple(VARIANTS), help="default single9x9")
    t.add_argument("--data", type=nonempty_path, metavar="DIR", help="shared data folder holding "
                   "middlebury2005_third/ and middlebury2006_third/ (default: ../shared/data)")
    t.add_argument("--objective", choices=("curve", "triplet"), help="curve (default): "
                   "softmax over the box-filtered cost of every candidate disparity of strips of "
                   "pixels; triplet: MC-CNN's hinge on one positive and one negative patch")
    t.add_argument("--epochs", type=positive_int, metavar="N", help="default 20")
    t.add_argument("--steps", type=positive_int, metavar="N",
                   help="batches per epoch (default 1000)")
    t.add_argument("--strips", type=positive_int, metavar="N",
                   help="strips per batch, curve (default 32)")
    t.add_argument("--batch", type=positive_int, metavar="N", help="triplets per batch, triplet "
                   "(default 256)")
    t.add_argument("--lr", type=finite_float, help="Adam learning rate, decaying linearly to 0 "
                   "(default 0.004)")
    t.add_argument("--seed", type=nonnegative_int, default=0, metavar="S")
    t.add_argument("--similarity", choices=("cosine", "tanh", "both"), help="triplet: hinge on "
                   "cosine (MC-CNN), on the tanh relaxation of the Hamming comparison (default), "
                   "or both")
    t.add_argument("--augment", default="basic", choices=sorted(RECIPES),
                   help="what training does to the views: basic (gain, offset, noise up to "
                   "sigma 2), robust (noise up to 10 with shot noise, gamma, defocus, 0.5 px "
                   "vertical misalignment) or mild (half those ranges); nna/training/augment.py")
    t.add_argument("--noise-max", type=finite_float, metavar="SIGMA",
                   help="augmentation noise: sigma ~ U(0, SIGMA) grey levels per view (default 2)")
    t.add_argument("--blur-max", type=finite_float, metavar="SIGMA",
                   help="augmentation defocus: Gaussian blur of sigma ~ U(0, SIGMA) px per view "
                   "(default: the recipe's; basic has none)")
    t.add_argument("--box", type=box_width, metavar="K", help="curve: the K x K box filter "
                   "of the cost the loss sees (odd, in sva.box_size's range; default 5)")
    t.add_argument("--leave-out-fold", type=parse_fold, metavar="K/N", help="train without "
                   "fold K of N of the tuning scenes (scene i of the sorted names is in fold "
                   "i mod N, as in benchmarks/tune_defaults.py), to cross-validate a recipe")
    t.add_argument("--aggregate", type=box_width, metavar="A", help="triplet: average the "
                   "similarity over A x A neighbouring descriptors, as the box filter does (odd)")
    t.add_argument("--threads", type=parse_threads, default=0, metavar="N", help="torch CPU "
                   "threads (default auto: 1 up to 2 CPUs, else half the CPUs, at most 4)")
    t.add_argument("--device", choices=DEVICES, default="cpu", help="where torch trains: cpu "
                   "(default) or cuda, a GPU torch sees (other weights than the CPU's, from the "
                   "same recipe and seed)")
    t.add_argument("--checkpoint-every", type=nonnegative_int, default=200, metavar="N",
                   help="write OUT.ckpt.pt every N steps (default 200; 0 = never)")
    t.add_argument("--resume", action="store_true", help="continue from OUT.ckpt.pt, the "
                   "checkpoint of an interrupted run with the same options")
    t.add_argument("--out", type=nonempty_path, metavar="FILE", help="float model .npz "
                   "(default: VARIANT.npz); with --qat the int8 artifact")
    t.add_argument("--qat", type=nonempty_path, metavar="BASE", help="quantisation-aware "
                   "fine-tuning of the float model BASE (written by train): quantise it, "
                   f"train through the chip's integer arithmetic ({QAT_EPOCHS} epochs at lr "
                   f"{QAT_LR} unless given; its augmentation unless given), write the int8 "
                   "artifact to --out")
    t.add_argument("--float-out", type=nonempty_path, metavar="FILE", help="with --qat: "
                   "also write the fine-tuned float weights (the float model the int8 bits "
                   "are compared with)")
    t.add_argument("--quiet", action="store_true", help="no progress bar and no notes on "
                   "stderr (the thread count, the quantiser's agreement)")
    t.set_defaults(func=cmd_train)


def _add_quantize_parser(sub) -> None:
    """``stereosim quantize``: a trained model to the NNA's int8 weights."""
    q = sub.add_parser("quantize", help="int8-quantise a trained model for the NNA")
    q.add_argument("model", type=nonempty_path,
                   help="float model .npz written by 'stereosim train'")
    q.add_argument("--calib", type=nonempty_path, required=True, metavar="DIR",
                   help="calibration scenes: the shared data folder (its training scenes), "
                   "a collection or one scene")
    q.add_argument("--out", type=nonempty_path, required=True, metavar="WEIGHTS",
                   help="quantized artifact .npz")
    q.add_argument("--calib-scenes", type=positive_int, default=8, metavar="N",
                   help="use the views of at most N scenes, spread evenly (default 8)")
    q.add_argument("--distance", default="hamming", choices=("hamming", "rms", "l1", "kl",
                   "hist_rms"), help="distance that picks the last layer's scales")
    q.add_argument("--hidden-distance", default="rms", choices=("hamming", "rms", "l1", "kl",
                   "hist_rms"), help="distance that picks the other layers' scales (default rms)")
    q.add_argument("--act-quantile", type=finite_float, default=0.9999, metavar="Q",
                   help="multi-layer: "
                   "each hidden layer's int8 activations map this quantile of its ReLU outputs "
                   "to 127 (default 0.9999; lower clips more and rounds finer)")
    q.add_argument("--no-equalize", dest="equalize", action="store_false",
                   help="multi-layer: keep each hidden layer's channels on the one activation "
                   "range the paper's quantiser gives them (default: every hidden channel is "
                   "first rescaled onto one range, the float function unchanged)")
    q.add_argument("--steps", type=int, default=1000, metavar="N",
                   help="scale candidates per channel (>= 1000)")
    q.add_argument("--z-bits", type=int, default=8, metavar="Z", help="m, h in [0, 2^Z - 1]")
    q.add_argument("--samples", type=positive_int, default=20000, metavar="N",
                   help="sampled pixels for the search")
    q.add_argument("--seed", type=nonnegative_int, default=0, metavar="S")
    q.add_argument("--quiet", action="store_true", help="no progress bar")
    q.set_defaults(func=cmd_quantize)
