"""The chip of a run, resolved once where the run starts: the checked configuration, the NNA's
spec (its network loaded once, :mod:`nna.descriptor`) and the SVA's (its derived widths,
:mod:`sva.spec`).

``stereosim.run`` and ``run_stream`` resolve it from the configuration they were given,
:func:`~sim.cycle.plan.build_plan` takes it (or resolves it from a bare configuration) and the
:class:`~sim.cycle.plan.ChipPlan` keeps it, so the engines, the estimate and the reports read
the network and the widths from the plan; nothing below the entry checks the configuration or
reads the weight file again.
"""

from __future__ import annotations

from dataclasses import dataclass

from stereosim.core.config import ChipConfig, check_config
from stereosim.nna.descriptor import NnaSpec, resolve_nna
from stereosim.sva.spec import SvaSpec, resolve_sva


@dataclass(frozen=True, slots=True, eq=False)
class ChipSpec:
    """A checked chip configuration, resolved (:func:`resolve_chip`): ``cfg`` the checked
    :class:`~core.config.schema.ChipConfig`, ``nna`` its :class:`~nna.descriptor.NnaSpec` (the
    loaded network, the descriptor's parts), ``sva`` its :class:`~sva.spec.SvaSpec` (the
    widths it derives for that descriptor)."""

    cfg: ChipConfig
    nna: NnaSpec
    sva: SvaSpec


def resolve_chip(cfg: ChipConfig, *, checked: bool = False) -> ChipSpec:
    """The :class:`ChipSpec` of ``cfg``: the configuration checked (:func:`core.config.
    check_config`: every value, every combination; ``checked=True`` where the caller holds
    what :func:`core.config.load_config` or ``check_config`` has just returned), then the NNA
    resolved (:func:`nna.descriptor.resolve_nna`: the network loaded and its rules checked) and the
    SVA for its descriptor (:func:`sva.spec.resolve_sva`). Raises :class:`ConfigError` with
    one line."""
    if not checked:
        cfg = check_config(cfg)
    nna = resolve_nna(cfg.nna, checked=True)
    return ChipSpec(cfg=cfg, nna=nna, sva=resolve_sva(cfg.sva, nna.part_bits, checked=True))
