"""Static figures of the modelled chip for one frame: SRAM bits per buffer, work per block.

These follow from the configuration and the image size alone (every descriptor performs all
its MACs, every pixel passes every buffer once), so they are exact for the model and the same in
both modes. Per-action counts let a user attach an energy per MAC, per SRAM read and per SRAM
write. Formulas are in the docstrings and in docs/architecture.md.
"""

from __future__ import annotations

import math

from nna.descriptor import descriptor_bits, layer
from nna.geometry import cycles_per_descriptor, half_window
from sim.config import ChipConfig


def _bits_for(max_value: int) -> int:
    return max(1, math.ceil(math.log2(max_value + 1)))


def output_word_bits(cfg: ChipConfig) -> int:
    """Bits of an SVA output word: a valid flag, ceil(log2 D) integer disparity bits and the
    sub-pixel fraction."""
    return 1 + _bits_for(cfg.sva.disparities - 1) + cfg.sva.subpixel_bits


def nna_to_sva_word_bits(cfg: ChipConfig) -> int:
    """Bits of a beat on the NNA -> SVA FIFOs: the descriptor, plus the 8-bit image intensity
    the adaptive P2 needs."""
    return descriptor_bits(cfg.nna) + (8 if cfg.sva.p2_adaptive else 0)


def nna_macs_per_descriptor(cfg: ChipConfig) -> int:
    """K*K*C multiply-accumulates of the CNN layer; census descriptors use no MACs."""
    if cfg.nna.descriptor == "census":
        return 0
    c, k, _ = layer(cfg.nna)[0].shape
    return k * k * c


def buffer_bits(cfg: ChipConfig, width: int) -> dict[str, int]:
    """SRAM bits of every buffer of the streaming design (per instance; NNA: per submodule).

    - ``nna.line_buffer``: line_buffer_rows x W x 8;
    - ``nna.weights`` (CNN only): K*K*C x 8 + C x 32 (int8 weights, int32 biases);
    - ``sva.descriptor_rows``: both views' descriptor rows the box filter slides over: 2 x (k + 1)
      x W x B (the entering and the leaving row are re-read to update the column sums);
    - ``sva.column_sums``: W x D x ceil(log2(k*B + 1)) (the vertical box sums);
    - ``sva.right_window``: D x B (the right descriptors x - D + 1 .. x of the current pixel);
    - ``sva.sgm_previous_row``: (paths - 1) x W x D x path_bits (top paths) + D x path_bits (the
      left-to-right path's previous pixel);
    - ``sva.lr_window``: W x (sum_bits + ceil(log2 D)) for the diagonal search and W x
      ceil(log2 D) for d* of the row, when the LR check is on;
    - ``sva.median_rows``: (median) rows x W x output-word bits, when the median is on.
    """
    s = cfg.sva
    bits = descriptor_bits(cfg.nna)
    d_bits = _bits_for(s.disparities - 1)
    word_bits = output_word_bits(cfg)
    out = {"nna.line_buffer": cfg.nna.line_buffer_rows * width * 8}
    if cfg.nna.descriptor == "cnn":
        c, k, _ = layer(cfg.nna)[0].shape
        out["nna.weights"] = k * k * c * 8 + c * 32
    out["sva.descriptor_rows"] = 2 * (s.box_size + 1) * width * bits
    out["sva.column_sums"] = width * s.disparities * _bits_for(s.box_size * bits)
    out["sva.right_window"] = s.disparities * bits
    out["sva.sgm_previous_row"] = (
        (s.paths - 1) * width * s.disparities * s.path_bits + s.disparities * s.path_bits
    )
    if s.lr_check:
        out["sva.lr_window"] = width * (s.sum_bits + d_bits) + width * d_bits
    if s.median > 1:
        out["sva.median_rows"] = s.median * width * word_bits
    return out


def action_counts(cfg: ChipConfig, shape: tuple[int, int]) -> dict[str, dict[str, int]]:
    """Per-frame counts of MACs and SRAM reads/writes per block (per camera for the NNA).

    NNA submodule: H*W line-buffer writes; reads: K*K per descriptor (CNN) or the census
    window's samples + 1 (census); MACs: K*K*C per descriptor. SVA: per pixel one write of each
    view's descriptor, D Hamming costs, and per pixel and path one D-vector read and write of
    path costs (top paths: previous-row buffer).
    """
    h, w = shape
    n = h * w
    s = cfg.sva
    if cfg.nna.descriptor == "census":
        win_w, win_h = cfg.nna.census.window
        reads = n * (win_w * win_h)
    else:
        _, k, _ = layer(cfg.nna)[0].shape
        reads = n * k * k
    top_paths = s.paths - 1
    return {
        "nna_per_camera": {
            "macs": n * nna_macs_per_descriptor(cfg),
            "sram_writes": n,
            "sram_reads": reads,
        },
        "sva": {
            "hamming_costs": n * s.disparities,
            "sram_writes": 2 * n + n * top_paths * s.disparities,
            "sram_reads": 2 * n * s.disparities + n * top_paths * s.disparities,
        },
    }


def architecture_report(cfg: ChipConfig, shape: tuple[int, int]) -> dict:
    h, w = shape
    bits = descriptor_bits(cfg.nna)
    buffers = buffer_bits(cfg, w)
    return {
        "descriptor_bits": bits,
        "nna_cycles_per_descriptor": cycles_per_descriptor(cfg.nna),
        "nna_window_rows": 2 * half_window(cfg.nna) + 1,
        "sram_bits": buffers,
        "sram_bits_total": {
            "nna_per_submodule": sum(v for k, v in buffers.items() if k.startswith("nna.")),
            "sva": sum(v for k, v in buffers.items() if k.startswith("sva.")),
        },
        "descriptor_bytes_per_frame_per_camera": h * w * bits // 8,
        "actions": action_counts(cfg, shape),
    }
