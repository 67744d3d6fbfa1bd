"""The SVA of a run, resolved once: the checked ``sva`` section and the widths it derives for the
descriptor it matches.

:func:`resolve_sva` checks the section (or trusts the caller that has just checked it) and
works out, once, what the plan and the reports read: the descriptor's parts as the SVA matches
them, the largest matching cost of a pixel and the output word's width. The SVA's functional
entry points (:mod:`sva.pipeline.pipeline`) take an :class:`SvaSpec` as checked, a raw section
after checking it (:func:`sva_config`).
"""

from __future__ import annotations

from dataclasses import dataclass

from stereosim.core.config import SvaConfig, check_section
from stereosim.core.config.widths import largest_cost, weight_sets
from stereosim.sva.geometry import output_word_bits


@dataclass(frozen=True, slots=True, eq=False)
class SvaSpec:
    """The SVA of a checked configuration (:func:`resolve_sva`): ``cfg`` the checked
    :class:`~core.config.schema.SvaConfig`; ``parts`` the bits of each part of the descriptor
    it matches (one, or the hybrid's CNN and census parts); ``cost_max`` the largest matching
    cost of a pixel (the hybrid's weighted, :func:`core.config.widths.largest_cost`);
    ``word_bits`` the output word's (:func:`sva.geometry.output_word_bits`)."""

    cfg: SvaConfig
    parts: tuple[int, ...]
    cost_max: int
    word_bits: int


def resolve_sva(section: SvaConfig, parts: tuple[int, ...], *, checked: bool = False
                ) -> SvaSpec:
    """The :class:`SvaSpec` of an ``sva`` section matching a descriptor of ``parts`` (each
    part's bits, :attr:`nna.descriptor.NnaSpec.part_bits`): the section checked
    (:func:`core.config.check_section`; ``checked=True`` where the caller holds what
    :func:`core.config.load_config` or :func:`core.config.check_config` has just returned)
    and its widths worked out."""
    cfg = section if checked else check_section(section, "sva.")
    parts = tuple(parts)
    return SvaSpec(cfg=cfg, parts=parts, cost_max=largest_cost(parts, weight_sets(cfg)),
                   word_bits=output_word_bits(cfg))


def sva_config(cfg: SvaSpec | SvaConfig) -> SvaConfig:
    """The checked section an SVA entry point runs with: a spec's (trusted: resolved where the
    run started), or a raw section checked now (:func:`core.config.check_section`, one line
    naming the first bad key)."""
    return cfg.cfg if isinstance(cfg, SvaSpec) else check_section(cfg, "sva.")
