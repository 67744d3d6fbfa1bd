"""The rule behind the SVA's automatic register widths.

The cost, path and sum registers (``sva.cost_bits``, ``path_bits``, ``sum_bits``) are keys of
the configuration: a user may set them, and ``stereosim config show`` prints the ones left unset
as "auto". So they are worked out when the configuration is loaded (:mod:`core.config.loader`),
before any chip plan exists, from this one rule; the schema's defaults use it too, and the plan
and the stages read the widths from the configuration.
"""

from __future__ import annotations

#: Output channels (descriptor bits) of the shipped 9x9x32 layer: the default of
#: ``nna.cnn.channels``, which the automatic register widths follow.
CNN_BITS = 32


def sgm_widths(p2: int, box: int = 5, bits: int = CNN_BITS, paths: int = 4) -> dict:
    """The narrowest cost, path and sum registers that never saturate: a box-filtered cost stays
    below ``box^2 * bits``, a path cost below that plus P2, the sum below ``paths`` path costs."""
    top = box * box * bits
    path_bits = (top + p2).bit_length()
    return {"cost_bits": top.bit_length(), "path_bits": path_bits,
            "sum_bits": (paths * ((1 << path_bits) - 1)).bit_length()}


def largest_cost(parts: tuple[int, ...], weight_sets: tuple[tuple[int, ...], ...]) -> int:
    """The largest matching cost of one pixel, which the automatic widths follow: a descriptor
    of one part, its bits; the hybrid's parts (b_0, b_1), sum_k w_k b_k for the heaviest of the
    weight sets the SVA may use (:mod:`sva.hamming.cost`)."""
    if len(parts) == 1:
        return parts[0]
    return max(1, max(sum(b * w for b, w in zip(parts, ws, strict=True)) for ws in weight_sets))


def weight_sets(sva) -> tuple[tuple[int, ...], ...]:
    """The weight sets a configured SVA (an :class:`~core.config.schema.SvaConfig`) may match a
    hybrid frame with: ``cost_weights``, and ``noisy_weights`` with ``weight_mode`` auto."""
    sets = (tuple(sva.cost_weights),)
    return sets + ((tuple(sva.noisy_weights),) if sva.weight_mode == "auto" else ())
