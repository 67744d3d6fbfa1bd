"""The networks and the losses of training (torch, imported inside the functions).

Objective ``curve``: the descriptors' relaxed bits ``tanh(a f)`` (:func:`relaxed_bits`; the
signs themselves, straight-through, at the end of a run) give the Hamming distance
``(C - b . b') / 2`` of every reference pixel to each of its candidates, box-filtered as the SVA
does (:func:`cost_curves`); the loss is the softmax cross-entropy of ``-cost / T`` against the
ground truth split between its two neighbouring integer disparities (:func:`curve_loss`), with
two small regularisers that keep every bit informative (:func:`bit_regularisers`).
Objective ``triplet``: a hinge loss on a similarity of the left, positive and negative patches'
descriptors (:func:`hinge_loss`, :func:`similarity`).
"""

from __future__ import annotations

from stereosim.nna.training.trainconfig import VARIANTS, TrainConfig


def build_network(variant: str):
    """The torch network of a variant: 'valid' convolutions, ReLU between layers."""
    import torch

    layers = []
    spec = VARIANTS[variant]
    for i, (c_in, c_out, k) in enumerate(spec):
        layers.append(torch.nn.Conv2d(c_in, c_out, k))
        if i < len(spec) - 1:
            layers.append(torch.nn.ReLU())
    return torch.nn.Sequential(*layers)


def similarity(f_a, f_b, kind: str):
    """Similarity of two batches of descriptors (B, C), or of descriptor maps (B, C, A, A):
    cosine or the tanh relaxation, at each of the A x A positions averaged over them."""
    import torch

    if kind == "cosine":
        per_pos = torch.nn.functional.cosine_similarity(f_a, f_b, dim=1, eps=1e-6)
    else:
        per_pos = (torch.tanh(f_a) * torch.tanh(f_b)).mean(dim=1)
    return per_pos if per_pos.ndim == 1 else per_pos.flatten(1).mean(dim=1)


def hinge_loss(f_l, f_p, f_n, cfg: TrainConfig):
    kinds = ("cosine", "tanh") if cfg.similarity == "both" else (cfg.similarity,)
    loss = 0.0
    for kind in kinds:
        s_pos = similarity(f_l, f_p, kind)
        s_neg = similarity(f_l, f_n, kind)
        loss = loss + (cfg.margin + s_neg - s_pos).clamp(min=0.0).mean()
    return loss


def relaxed_bits(f, scale: float, sign: bool):
    """The descriptor bits as +-1: ``tanh(scale * f)``, or with ``sign`` the signs themselves
    with the gradient of the tanh (straight-through)."""
    import torch

    soft = torch.tanh(scale * f)
    if not sign:
        return soft
    return soft + (torch.sign(f) - soft).detach()


def cost_curves(b_ref, b_other, disparities: int, box: int):
    """Box-filtered relaxed Hamming costs (S, Ws, D) on the scale of one descriptor, 0..C.

    ``b_ref`` (S, C, box, Ws + box - 1) and ``b_other`` (S, C, box, Ws + box - 1 + D - 1) are
    +-1 bit maps (:func:`relaxed_bits`) in the left-reference geometry: column j of the
    reference matches column j + D - 1 - d of the other map at disparity d. The Hamming
    distance of two +-1 vectors is ``(C - a . b) / 2``; the box filter of the SVA is the mean
    over the box x box window (the chip's sum divided by box^2).
    """
    import torch

    n_ref, n_other = b_ref.shape[3], b_other.shape[3]
    # every reference column against every other column of the same row, then the band of
    # the D candidates of each reference column
    dots = b_ref.permute(0, 2, 3, 1) @ b_other.permute(0, 2, 1, 3)  # (S, box, n_ref, n_other)
    band = dots.as_strided(
        (dots.shape[0], dots.shape[1], n_ref, disparities),
        (dots.stride(0), dots.stride(1), n_other + 1, 1),
    ).flip(-1)
    cost = 0.5 * (b_ref.shape[1] - band)  # (S, box, n_ref, D)
    cost = cost.mean(dim=1).permute(0, 2, 1)  # (S, D, n_ref): the box's rows
    cost = torch.nn.functional.avg_pool1d(cost, box, stride=1)  # and its columns
    return cost.permute(0, 2, 1)


def curve_loss(cost, target, max_disp, log_temp):
    """Softmax cross-entropy over the candidate disparities of every usable reference pixel.

    ``-cost / T`` are the logits (T = exp(log_temp), learnt); candidates whose match lies
    outside the other view are left out; the target splits between the two integer
    disparities around the (sub-pixel) ground truth, in proportion to their closeness.
    """
    import torch

    grid = torch.arange(cost.shape[2], dtype=cost.dtype, device=cost.device)
    logits = (-cost / log_temp.exp()).masked_fill(grid > max_disp[..., None], -1e4)
    usable = torch.isfinite(target)
    gt = torch.nan_to_num(target, nan=0.0)
    weight = (1.0 - (grid - gt[..., None]).abs()).clamp(min=0.0)
    ce = -(weight * torch.nn.functional.log_softmax(logits, dim=-1)).sum(dim=-1)
    return ce[usable].mean() if bool(usable.any()) else cost.sum() * 0.0


def bit_regularisers(bits):
    """(balance, decorrelation) of the +-1 bit maps (S, C, ...): the squared mean of each bit
    (0 when a bit is 1 as often as -1) and the squared off-diagonal correlations between bits
    (0 when the bits are uncorrelated), each averaged, so every bit carries information."""
    import torch

    c = bits.shape[1]
    z = bits.transpose(0, 1).reshape(c, -1)
    mean = z.mean(dim=1)
    z = z - mean[:, None]
    cov = (z @ z.T) / z.shape[1]
    std = cov.diagonal().clamp(min=1e-6).sqrt()
    corr = cov / std[:, None] / std[None, :]
    off = corr - torch.eye(c, dtype=corr.dtype, device=corr.device)
    return (mean * mean).mean(), (off * off).sum() / (c * (c - 1))
