"""Training the learned descriptor in torch, on the CPU (or a CUDA GPU, ``device``): the run loop.

The pieces, one module each: the settings and the three variants (:mod:`nna.training.trainconfig`),
the scenes and batches (:mod:`nna.training.traindata`), the networks and losses
(:mod:`nna.training.trainloss`), the
output file (:mod:`nna.training.floatmodel`), the thread count, checkpoints and resuming a long run
(:mod:`nna.training.trainrun`). :func:`train` draws a batch, takes one step of the objective and
keeps the history.

ReLU between layers, none after the last. Training uses 'valid' convolutions on crops; at
inference the same weights run on whole images with the chip's replicate border
(:mod:`quant.quantizer` ``float_forward``), identical away from the border. The descriptor the
chip uses is the **sign** of each output.

Two objectives:

* ``curve`` (default): what the SVA's winner-take-all sees after the box filter, with every
  negative. A batch is ``strips`` strips of ``strip_width`` consecutive reference pixels of one
  row, the reference view being the left or the right view of a scene (each with its own GT,
  ``disp1.png`` / ``disp5.png``). One convolution over the (9 + box - 1)-row crop of the
  reference view and over the matching crop of the other view, ``disparities - 1`` columns
  longer, gives the descriptors; their relaxed bits ``tanh(a f)`` give the Hamming distance
  ``(C - b . b') / 2`` of every reference pixel to each of its ``disparities`` candidates, which
  is box-filtered as the SVA does (:func:`~nna.training.trainloss.cost_curves`). The loss is the
  softmax cross-entropy of ``-cost / T`` (T learnt) against the ground truth split between its two
  neighbouring integer disparities (:func:`~nna.training.trainloss.curve_loss`). The tanh scale
  ``a`` grows geometrically from ``scale_start`` to ``scale_end`` so the relaxation tends to the
  signs, and the last ``sign_fraction`` of the run uses the signs themselves (straight-through
  gradient, :func:`~nna.training.trainloss.relaxed_bits`), so the network is trained for the Hamming
  costs the chip computes. Two small regularisers keep every bit informative
  (:func:`~nna.training.trainloss.bit_regularisers`): its mean over the batch (balanced bits) and
  the correlations between bits.
* ``triplet``: MC-CNN's recipe. For a left pixel (x, y) with known, non-occluded ground truth
  d, the positive right patch is centred at x - d + U(-pos, pos), the negative one at
  x - d +- U(neg_low, neg_high), both interpolated linearly along the row; hinge loss
  ``max(0, margin + s(L, N) - s(L, P))`` on a similarity s: ``cosine`` (MC-CNN's), ``tanh``
  (``s = mean_c tanh(f_L[c]) tanh(f_R[c])``, which for outputs of large magnitude tends to
  ``1 - 2 * Hamming(sign f_L, sign f_R) / 32``) or ``both``. With ``aggregate = A > 1`` the
  patches grow to (8 + A) x (8 + A) and the similarity is averaged over the A x A map.

Input normalisation is the NNA's: ``x = (pixel - input_offset) * input_scale`` with two
constants fixed before training (recorded in the output file), nothing per patch.

torch is imported only inside the functions that need it: the rest of stereosim does not
depend on it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import asdict

import numpy as np

from stereosim.core.errors import InputError
from stereosim.core.progress import progress_bar
from stereosim.nna.training.trainconfig import TrainConfig
from stereosim.nna.training.traindata import (
    load_strip_set,
    load_training_set,
    sample_batch,
    sample_strips,
)
from stereosim.nna.training.trainloss import (
    bit_regularisers,
    build_network,
    cost_curves,
    curve_loss,
    hinge_loss,
    relaxed_bits,
)
from stereosim.nna.training.trainrun import (
    load_checkpoint,
    pick_threads,
    restore,
    save_checkpoint,
    snapshot,
    threads_line,
    training_device,
    use_threads,
)


def _scale_at(cfg: TrainConfig, frac: float) -> float:
    """The tanh scale after ``frac`` of the run: geometric from scale_start to scale_end."""
    return cfg.scale_start * (cfg.scale_end / cfg.scale_start) ** frac


def _curve_step(net, batch, cfg: TrainConfig, frac: float, log_temp):
    import torch

    dev = log_temp.device

    def tensor(key):
        return torch.from_numpy(batch[key]).to(dev)

    def features(key):
        x = (tensor(key) - float(cfg.input_offset)) * cfg.input_scale
        return net(x[:, None])

    f_ref, f_other = features("ref"), features("other")
    mirror = tensor("mirror")[:, None, None, None]
    f_ref = torch.where(mirror, f_ref.flip(3), f_ref)
    f_other = torch.where(mirror, f_other.flip(3), f_other)
    scale, sign = _scale_at(cfg, frac), frac >= 1.0 - cfg.sign_fraction
    b_ref, b_other = relaxed_bits(f_ref, scale, sign), relaxed_bits(f_other, scale, sign)
    cost = cost_curves(b_ref, b_other, cfg.disparities, cfg.box)
    loss = curve_loss(cost, tensor("target"), tensor("max_disp"), log_temp)
    if cfg.balance or cfg.decorrelate:
        bal, dec = bit_regularisers(b_ref)
        loss = loss + cfg.balance * bal + cfg.decorrelate * dec
    return loss


def train(cfg: TrainConfig, scene_dirs, *, progress: bool = True, checkpoint=None,
          checkpoint_every: int = 0, resume: bool = False, log=None, make_net=None) -> dict:
    """Train one network; returns the arrays and metadata :func:`save_float_model` writes.

    ``cfg.threads`` 0 picks the thread count (:func:`nna.training.trainrun.pick_threads`; the result
    records the count used). With ``checkpoint`` (a path) and ``checkpoint_every`` N > 0 the
    state is written there every N steps; ``resume`` continues from it, to the same weights as
    an uninterrupted run (:mod:`nna.training.trainrun`). ``log(line)`` receives the line that says
    how many threads the run uses, before the first step. ``make_net()``: builds the network to
    train instead of a fresh one of ``cfg.variant`` (a QAT network, :mod:`nna.training.trainqat`),
    after the seeds are set."""
    import torch

    requested = cfg.threads
    cfg = dataclasses.replace(cfg, threads=pick_threads(requested))
    use_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    dev = training_device(cfg.device)  # before the scenes load: a missing GPU stops at once
    rng = np.random.default_rng(cfg.seed)
    if cfg.objective == "curve":
        data = load_strip_set(scene_dirs, cfg)
        n_samples = data.image.size
    else:
        data = load_training_set(scene_dirs, cfg)
        n_samples = data.scene.size
    if n_samples == 0:
        raise InputError("the training scenes have no pixel with usable ground truth")
    net = (build_network(cfg.variant) if make_net is None else make_net()).to(dev)
    params = list(net.parameters())
    log_temp = torch.nn.Parameter(torch.tensor(float(np.log(cfg.temperature)), device=dev))
    if cfg.objective == "curve":
        params.append(log_temp)
    opt = torch.optim.Adam(params, lr=cfg.lr)
    total = cfg.epochs * cfg.steps_per_epoch
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda step: 1.0 - step / total)
    run = {"step": 0, "history": [], "running": 0.0}
    if resume:
        saved = load_checkpoint(checkpoint, asdict(cfg), data.names)
        restore(saved, net, log_temp, opt, sched, rng, checkpoint)
        run = {k: saved[k] for k in run}
    if log is not None:
        log(threads_line(cfg.threads, requested))
    bar = progress_bar(total, f"train {cfg.variant}", "step", quiet=not progress,
                       initial=run["step"])
    with bar:
        for step in range(run["step"], total):
            epoch, k = divmod(step, cfg.steps_per_epoch)
            if cfg.objective == "curve":
                loss = _curve_step(net, sample_strips(data, cfg, rng), cfg, step / total, log_temp)
            else:
                loss = _triplet_step(net, sample_batch(data, cfg, rng), cfg)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            run["running"] += loss.item()
            if k == cfg.steps_per_epoch - 1:
                run["history"].append(run["running"] / cfg.steps_per_epoch)
                run["running"] = 0.0
            run["step"] = step + 1
            bar.update(1)
            bar.set_postfix(epoch=epoch + 1, loss=f"{loss.item():.4f}", refresh=False)
            if checkpoint is not None and checkpoint_every > 0 and run["step"] < total \
                    and run["step"] % checkpoint_every == 0:
                state = {**snapshot(net, log_temp, opt, sched, rng), **run}
                save_checkpoint(checkpoint, state, asdict(cfg), data.names)
    weights, biases = _float_layers(net)
    return {
        "weights": weights,
        "biases": biases,
        "config": asdict(cfg),
        "scenes": list(data.names),
        "loss_per_epoch": run["history"],
        "samples": int(n_samples),
    }


def _float_layers(net) -> tuple[list, list]:
    """The trained float weights and biases (float32 numpy) of a plain or a QAT network."""
    import torch

    if hasattr(net, "float_layers"):
        return net.float_layers()
    convs = [m for m in net if isinstance(m, torch.nn.Conv2d)]
    return ([c.weight.detach().cpu().numpy().astype(np.float32) for c in convs],
            [c.bias.detach().cpu().numpy().astype(np.float32) for c in convs])


def _triplet_step(net, batch, cfg: TrainConfig):
    import torch

    dev = next(net.parameters()).device
    x = (torch.from_numpy(batch).to(dev) - float(cfg.input_offset)) * cfg.input_scale
    f = net(x.reshape(3 * cfg.batch, 1, *batch.shape[2:]))
    if cfg.aggregate == 1:
        f = f.reshape(3, cfg.batch, -1)
    else:
        f = f.reshape(3, cfg.batch, *f.shape[1:])
    return hinge_loss(f[0], f[1], f[2], cfg)
