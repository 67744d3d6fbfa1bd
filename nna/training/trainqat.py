"""Quantisation-aware training (QAT): the chip's integer arithmetic in the forward pass.

A fine-tuning phase after float training. The project's quantiser (:func:`quant.quantizer.quantize`,
the paper's Algorithm 3) first turns the trained float network into an integer one; its per-channel
weight scales ``s``, the activation scales ``a_l`` and the multiply-shift pairs ``(m, h)`` are then
**frozen**, and training continues on the float weights ``W`` and biases ``B`` (those of the
float model the scales belong to: the quantiser's rescaled twin,
:func:`quant.quantizer.quantize_twin`, when it equalises the hidden channels) with every layer
computed as the NNA computes it (:mod:`quant.intconv`):

    x_0     = round(x / input_scale)                           (pixel - input_offset, exact)
    W_int   = clamp(round(W * s), -128, 127)                   (int8, per output channel)
    B_int   = clamp(round(B * s * a_l), -L, L)                 (int32, worst case in int32)
    acc     = B_int + conv(x_l, W_int)
    x_{l+1} = clamp(floor(acc * m * 2**-h), 0, 127)            (the multiply-shift and ReLU_127)

and the last layer's accumulator divided by ``s * a_L`` as the descriptor outputs the loss sees
(their signs are the chip's bits). Rounding and the floor pass the gradient straight through
(the gradient of the identity); the clamps pass it where they do not clamp. ``round`` is
half-to-even, as the quantiser's ``np.rint``.

Exactness. The integer weights and biases are formed in float64 (exact integers); the
convolutions run in ``dtype`` (float32 in training, float64 to check); the multiply-shift runs
in float64, where ``acc * m`` (below 2**47) and the division by a power of two are exact, so
the floor is the chip's arithmetic shift. In float64 the forward pass equals
:func:`quant.intconv.int_forward_ref` exactly (``tests/nna/training/test_trainqat.py``); in
float32 it is exact while every partial sum of a convolution stays below 2**24.

The exported artifact (:func:`export_quantized`) holds the QAT's own integer weights and biases
with the frozen scales and multiply-shift pairs, in the quantiser's format
(:mod:`quant.artifact`). torch is imported only inside the functions that need it.
"""

from __future__ import annotations

import functools

import numpy as np

from stereosim.quant.artifact import QuantizedModel, check_quantized
from stereosim.quant.intconv import ACT_MAX, INT32_MAX, int_forward
from stereosim.quant.quantizer import FloatModel, float_forward


def _round_ste(v):
    import torch

    return v + (torch.round(v) - v).detach()


def _floor_ste(v):
    import torch

    return v + (torch.floor(v) - v).detach()


@functools.cache
def _qat_class():
    import torch
    import torch.nn.functional as F

    class QatNet(torch.nn.Module):
        """Float weights trained through the frozen integer arithmetic of a quantised model."""

        def __init__(self, model: FloatModel, qm: QuantizedModel, dtype):
            super().__init__()
            self.weights = torch.nn.ParameterList(
                [torch.nn.Parameter(torch.tensor(np.asarray(w), dtype=torch.float32))
                 for w in model.weights])
            self.biases = torch.nn.ParameterList(
                [torch.nn.Parameter(torch.tensor(np.asarray(b), dtype=torch.float32))
                 for b in model.biases])
            self.dtype = dtype
            self.input_scale = float(qm.input_scale)
            x_max = max(qm.input_offset, 255 - qm.input_offset)
            self.x_max = [float(x_max)] + [float(ACT_MAX)] * (qm.n_layers - 1)
            self.act = [float(a) for a in qm.act_scales]
            # the frozen scales and multiply-shift pairs: buffers, so that .to(device) moves
            # them with the weights; not persistent, so a checkpoint holds the weights alone
            frozen = {"scale": [np.asarray(s, np.float64) for s in qm.weight_scales],
                      "mult": [np.asarray(m, np.float64) for m in qm.mult],
                      "pow": [np.ldexp(1.0, -np.asarray(h, np.int64)) for h in qm.shift]}
            self._counts = {name: len(arrays) for name, arrays in frozen.items()}
            for name, arrays in frozen.items():
                for i, a in enumerate(arrays):
                    self.register_buffer(f"{name}{i}", torch.tensor(a), persistent=False)

        def _frozen(self, name):
            """The frozen tensors ``name`` layer by layer: ``scale`` of every layer, ``mult``
            and ``pow`` (2^-shift) of every layer but the last."""
            return [self.get_buffer(f"{name}{i}") for i in range(self._counts[name])]

        @property
        def scale(self):
            return self._frozen("scale")

        @property
        def mult(self):
            return self._frozen("mult")

        @property
        def pow(self):
            return self._frozen("pow")

        def integer_params(self):
            """Per layer ``(W_int, B_int)`` as float64 tensors holding integers (STE grads)."""
            out = []
            for w, b, s, a, x_max in zip(self.weights, self.biases, self.scale, self.act,
                                         self.x_max):
                w_int = _round_ste(w.double() * s[:, None, None, None]).clamp(-128.0, 127.0)
                limit = INT32_MAX - w_int.detach().abs().sum(dim=(1, 2, 3)) * x_max
                b_int = torch.minimum(torch.maximum(_round_ste(b.double() * s * a), -limit),
                                      limit)
                out.append((w_int, b_int))
            return out

        def accumulators(self, x_int, same: bool = False):
            """The last layer's accumulators for integer inputs (N, 1, H, W) ('valid'
            convolutions; ``same``: the chip's replicate border, output as large as the input)."""
            params = self.integer_params()
            x = x_int.to(self.dtype)
            for layer, (w_int, b_int) in enumerate(params):
                if same:
                    r = w_int.shape[2] // 2
                    x = F.pad(x, (r, r, r, r), mode="replicate")
                acc = F.conv2d(x, w_int.to(self.dtype), b_int.to(self.dtype))
                if layer == len(params) - 1:
                    return acc
                m = self.mult[layer][None, :, None, None]
                p = self.pow[layer][None, :, None, None]
                x = _floor_ste(acc.double() * m * p).clamp(0.0, float(ACT_MAX)).to(self.dtype)
            raise AssertionError("unreachable")

        def forward(self, x):
            """Descriptor outputs in float units from normalised inputs (N, 1, H, W), as the
            float network takes them: the accumulators over ``s * a_L``."""
            acc = self.accumulators(torch.round(x.double() / self.input_scale))
            acc_scale = (self.scale[-1] * self.act[-1])[None, :, None, None]
            return (acc.double() / acc_scale).to(x.dtype)

        def float_layers(self):
            """The float weights and biases (the latent network) as float32 numpy arrays."""
            return ([w.detach().cpu().numpy().astype(np.float32) for w in self.weights],
                    [b.detach().cpu().numpy().astype(np.float32) for b in self.biases])

    return QatNet


def build_qat_net(model: FloatModel, qm: QuantizedModel, dtype=None):
    """A QAT network: ``model``'s float weights as parameters, ``qm``'s scales and
    multiply-shift pairs frozen. ``dtype`` of the convolutions: float32 (default) or float64."""
    import torch

    return _qat_class()(model, qm, torch.float32 if dtype is None else dtype)


def integer_network(net) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The QAT network's int8 weights and int32 biases, as numpy arrays."""
    import torch

    with torch.no_grad():
        params = net.integer_params()
    return ([w.cpu().numpy().astype(np.int8) for w, _ in params],
            [b.cpu().numpy().astype(np.int32) for _, b in params])


def export_quantized(model: FloatModel, qm: QuantizedModel, images,
                     calibration: str) -> QuantizedModel:
    """The artifact of a QAT run whose float weights are ``model``: the integer weights and
    biases its QAT network computes with ``qm``'s frozen scales and multiply-shift pairs; sign
    agreement and accumulator RMS measured against ``model`` on every pixel of ``images``
    (uint8 views of training scenes)."""
    weights, biases = integer_network(build_qat_net(model, qm))
    args = (tuple(weights), tuple(biases), qm.mult, qm.shift, qm.input_offset, qm.z_bits)
    acc = [int_forward(im, *args) for im in images]
    flt = [float_forward(model, im) for im in images]
    acc_all = np.concatenate([a.reshape(-1, a.shape[-1]) for a in acc]).astype(np.float64)
    f_all = np.concatenate([f.reshape(-1, f.shape[-1]) for f in flt])
    acc_scale = np.asarray(qm.weight_scales[-1]) * qm.act_scales[-1]
    out = QuantizedModel(
        weights=tuple(weights), biases=tuple(biases), mult=qm.mult, shift=qm.shift,
        input_offset=qm.input_offset, input_scale=qm.input_scale, z_bits=qm.z_bits,
        weight_scales=qm.weight_scales, act_scales=qm.act_scales, distances=qm.distances,
        sign_agreement=float(np.mean((acc_all > 0) == (f_all > 0))),
        acc_rms=float(np.sqrt(np.mean((acc_all - f_all * acc_scale) ** 2))),
        variant=qm.variant, calibration=calibration,
    )
    check_quantized(out)
    return out
