"""What AVX-512 VNNI would give the NNA's convolution: the shipped single9x9 layer on a 720p view,
computed by the simulator (float32 lanes, quant/intconv.py) and by uint8 x int8 dot products
(``vpdpbusd``: 64 products an instruction), same run, same descriptors required bit for bit.

    python benchmarks/vnni_probe.py [--repeat 5]

A measurement for issue 35 (the data kernels' share), not a kernel of the simulator: numba
does not vectorise the convolution into ``vpdpbusd`` by itself, so this probe reaches the
instruction through an ``@intrinsic`` (LLVM's ``llvm.x86.avx512.vpdpbusd.512``), the way
sva/cost.py reaches ``llvm.ctpop``. The layer as integers: the tap sum of the offset pixels is
``sum w * p - offset * sum w``; with the uint8 pixels packed four to an int32 (``quads``: a
pixel and the three to its right) and the kernel row's 9 taps in three groups of four (the
last padded with zero weights), each 16-pixel block of a channel takes 9 x 3 instructions.
A CPU without AVX512-VNNI gets one line and exit 2.
"""

from __future__ import annotations

import argparse
import sys
import time

import cv2
import numpy as np
from llvmlite import binding, ir
from machine import describe
from numba import njit, types
from numba.extending import intrinsic

from stereosim.nna.descriptor import compute_descriptor, network
from stereosim.sim.config import load_config
from stereosim.sim.datasets import default_scene
from stereosim.sim.io import to_grey

LANES = 16  # int32 lanes of a zmm register
GROUP = 4  # uint8 x int8 products per lane and instruction


@intrinsic
def _dpbusd_groups3(typingctx, acc, i, q, j, w0, w1, w2):
    """acc[i:i+16] += sum over g of dot4(bytes of q[j + 4 g + lane], bytes of w_g), the
    accumulator held in a register across the three groups."""
    sig = types.void(acc, i, q, j, w0, w1, w2)

    def codegen(context, builder, signature, args):
        acc_v, i_v, q_v, j_v = args[:4]
        acc_a = context.make_array(signature.args[0])(context, builder, acc_v)
        q_a = context.make_array(signature.args[2])(context, builder, q_v)
        vt = ir.VectorType(ir.IntType(32), LANES)
        fn = builder.module.declare_intrinsic("llvm.x86.avx512.vpdpbusd.512",
                                              fnty=ir.FunctionType(vt, [vt, vt, vt]))
        pa = builder.bitcast(builder.gep(acc_a.data, [i_v]), vt.as_pointer())
        a = builder.load(pa, align=4)
        for g, w_v in enumerate(args[4:]):
            jj = builder.add(j_v, ir.Constant(j_v.type, GROUP * g))
            b = builder.load(builder.bitcast(builder.gep(q_a.data, [jj]), vt.as_pointer()),
                             align=4)
            wv = builder.insert_element(ir.Constant(vt, ir.Undefined), w_v,
                                        ir.Constant(ir.IntType(32), 0))
            wv = builder.shuffle_vector(wv, ir.Constant(vt, ir.Undefined),
                                        ir.Constant(vt, [0] * LANES))
            a = builder.call(fn, [a, b, wv])
        builder.store(a, pa, align=4)
        return context.get_dummy_value()

    return sig, codegen


@njit(cache=True)
def _quads(padded, q):
    """q[y, x] = the four uint8 padded[y, x .. x + 3] packed little-endian into a uint32."""
    for y in range(q.shape[0]):
        row = padded[y]
        for x in range(q.shape[1]):
            q[y, x] = (np.uint32(row[x]) | (np.uint32(row[x + 1]) << 8)
                       | (np.uint32(row[x + 2]) << 16) | (np.uint32(row[x + 3]) << 24))


@njit(cache=True)
def _sign_layer_vnni(q, wq, threshold, masks, acc, out):
    """out[y, x] = OR of masks[c] over the channels whose tap sum of the raw pixels exceeds
    threshold[c] (= offset * sum w_c - bias_c); wq[c, ky] = the kernel row's three groups."""
    rows, width = out.shape
    k = wq.shape[1]
    for y in range(rows):
        bits = out[y]
        bits[:] = 0
        for c in range(wq.shape[0]):
            a = acc
            a[:] = 0
            for ky in range(k):
                qr = q[y + ky]
                w0, w1, w2 = wq[c, ky, 0], wq[c, ky, 1], wq[c, ky, 2]
                for x in range(0, width, LANES):
                    _dpbusd_groups3(a, x, qr, x, w0, w1, w2)
            t, m = threshold[c], masks[c]
            for x in range(width):
                if a[x] > t:
                    bits[x] |= m


def vnni_descriptor(img: np.ndarray, weights: np.ndarray, bias: np.ndarray,
                    offset: int) -> np.ndarray:
    """The single-layer K x K descriptor (K <= 12) of ``img`` by dot products of bytes."""
    c_out, _, k, _ = weights.shape
    r = k // 2
    h, w = img.shape
    wide = -(-w // LANES) * LANES  # whole 16-pixel blocks (the extra columns are dropped)
    padded = cv2.copyMakeBorder(img, r, r, r, r + (wide - w) + 3 * GROUP,
                                cv2.BORDER_REPLICATE)
    q = np.empty((h + 2 * r, wide + 2 * GROUP), np.uint32)
    _quads(padded, q)
    taps = np.zeros((c_out, k, 3 * GROUP), np.int8)
    taps[:, :, :k] = weights[:, 0]
    wq = taps.view(np.int32).reshape(c_out, k, 3).copy()
    threshold = (offset * weights.astype(np.int64).sum(axis=(1, 2, 3))
                 - bias.astype(np.int64)).astype(np.int32)
    masks = np.array([1 << c for c in range(c_out)], np.uint32)
    out = np.empty((h, wide), np.uint32)
    _sign_layer_vnni(q, wq, threshold, masks, np.empty(wide, np.int32), out)
    return out[:, :w]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    features = binding.get_host_cpu_features()
    if not features.get("avx512vnni", False):
        print("vnni_probe: this CPU has no AVX512-VNNI; the probe needs it (run it on one that "
              "has, e.g. AMD Zen 4 or Intel Ice Lake and later)", file=sys.stderr)
        return 2
    print(f"machine: {describe()}")
    cfg = load_config(overrides={"nna.descriptor": "cnn"}).nna
    weights, biases, _, _, offset = network(cfg).args[:5]
    if len(weights) != 1 or weights[0].shape[1] != 1 or weights[0].shape[2] > 3 * GROUP:
        print("vnni_probe: the default network is not one layer of K <= 12 on the grey image",
              file=sys.stderr)
        return 2
    scene = default_scene()
    img = cv2.resize(to_grey(scene["left"]), (1280, 720), interpolation=cv2.INTER_LINEAR)
    shipped = compute_descriptor(img, cfg)
    probe = vnni_descriptor(img, weights[0], biases[0], int(offset))
    if not np.array_equal(shipped, probe):
        print("vnni_probe: the dot-product descriptors differ from the simulator's",
              file=sys.stderr)
        return 1
    macs = img.size * weights[0].size
    for name, fn in (("simulator (float32 lanes)", lambda: compute_descriptor(img, cfg)),
                     ("vpdpbusd probe", lambda: vnni_descriptor(img, weights[0], biases[0],
                                                                int(offset)))):
        best = min(_timed(fn) for _ in range(args.repeat))
        print(f"  {name:26s}: {best:.4f} s per 720p view, {macs / best / 1e9:.1f} G MAC/s")
    print("  descriptors equal bit for bit")
    return 0


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


if __name__ == "__main__":
    sys.exit(main())
