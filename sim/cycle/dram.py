"""The DRAM channel of the chip plan (``dram.model = "tdm"``, docs/dram.md): its clients, the
slots each owns in every round, and the rules that size them. Built by
:func:`sim.cycle.plan.build_plan`; the engines read it as ``ChipPlan.dram``."""

from __future__ import annotations

import math
from dataclasses import dataclass

from stereosim.core.config import ChipConfig
from stereosim.core.errors import ConfigError


@dataclass(frozen=True)
class DramClient:
    """A client of the DRAM channel: the slots it owns in every round (offsets ``first`` ..
    ``first + count - 1``) and the bytes it moves per pixel of a view (a what-if's load)."""

    name: str
    first: int
    count: int
    bytes_per_pixel: float
    what: str


@dataclass(frozen=True)
class DramPlan:
    """The DRAM channel, time-division multiplexed (:mod:`sim.cycle.rules`, docs/dram.md).

    A round has one slot per client burst in step with the pixels: for every ``read_pixels``
    pixels of a view (one burst of each view read), the cameras' writes of as many pixels, the
    write-back of as many words, the spill's and the lent network's bursts. The memory sources
    request a pair of bursts (both views, the slots ``reads.first`` and the next) once their
    ``prefetch`` buffers have a free burst; the sink writes a burst of ``write_words`` words once
    its last word is in, holding at most ``write_buffer`` bursts."""

    slot_fs: int  # one burst at the peak bandwidth
    latency_fs: int  # a read slot's end to its data in the chip
    round_slots: int
    clients: tuple[DramClient, ...]
    burst_bytes: int
    read_pixels: int  # pixels of a view per read burst (one byte each)
    prefetch: int  # read bursts per view requested ahead of the pixels sent
    write_words: int  # disparity words per write-back burst
    write_buffer: int  # bursts the sink's write buffer holds

    def client(self, name: str) -> DramClient | None:
        return next((c for c in self.clients if c.name == name), None)

    @property
    def reads(self) -> DramClient | None:
        return self.client("read")

    @property
    def write_back(self) -> DramClient:
        return self.client("write_back")

    @property
    def round_fs(self) -> int:
        return self.round_slots * self.slot_fs

    @property
    def longest_wait_fs(self) -> int:
        """The longest a read may legitimately keep the chip waiting with nothing moving: a
        request just after its round's read slots waits for the next round and its two slots
        (at most a round each), then the access latency (``rules.dram_read_ready_fs``). The
        watchdog and the automatic cycle budget allow it."""
        return 2 * self.round_fs + self.latency_fs

    def gbps(self, client: DramClient) -> float:
        """The bandwidth a client's slots give it, GB/s."""
        return client.count * self.burst_bytes * 1e15 / self.round_fs / 1e9

    def read_bound_fps(self, pixels: int, without: str = "") -> float | None:
        """The frame rate the read slots allow a frame of ``pixels`` pixels a view: a round
        per read burst, ceil(pixels / read_pixels) rounds; ``without``: a client whose slots the
        rounds would not have. None without read slots (a camera streaming into the NNA)."""
        if self.reads is None:
            return None
        gone = self.client(without).count if without and self.client(without) else 0
        round_fs = (self.round_slots - gone) * self.slot_fs
        return round(1e15 / (-(-pixels // self.read_pixels) * round_fs), 3)


def dram_plan(cfg: ChipConfig, reads: bool, camera_writes: bool, beat_bits: int,
              word_bits: int, descriptor_bits: int, camera_hz: float, line_share: float,
              lent_gbps: float = 0.0) -> DramPlan:
    """The channel's slots; ``lent_gbps``: the traffic of the network on the lent NNA
    submodules (:attr:`sim.cycle.lent.LentPlan.gbps`). Raises ConfigError when it cannot absorb
    the cameras' writes (a camera cannot wait) or the lent network's traffic."""
    d = cfg.dram
    slot_fs = max(1, round(d.burst_bytes * 1e15 / (d.gbps * 1e9)))
    px = d.burst_bytes  # pixels of a view per read burst: one byte each
    wpb = max(1, d.burst_bytes * 8 // word_bits)
    spill = {"none": 0.0, "descriptors": 2 * 2 * beat_bits / 8,
             "float32": 2 * 2 * descriptor_bits * 4.0}[d.spill]
    clients: list[DramClient] = []

    def add(name, count, bpp, what):
        first = sum(c.count for c in clients)
        clients.append(DramClient(name, first, count, bpp, what))

    if reads:
        add("read", 2, 2.0, "the stereo pair read by the memory sources (left, right)")
    if camera_writes:
        add("camera_write", 2 * cfg.sva.pairs, 2.0,  # pairs' frames overlap: a slot each
            "the cameras' frames written into the frame buffers")
    add("write_back", -(-px // wpb), word_bits / 8, "the disparity words written back")
    if spill:
        add("spill", -(-round(spill * px) // d.burst_bytes), spill,
            f"{d.spill} written by the NNA and read back by the SVA (both views)")
    base = sum(c.count for c in clients)
    if lent_gbps > 0:  # whole slots a round, at least one: a light network is charged more
        x = lent_gbps / d.gbps
        if x >= 1:
            raise ConfigError(
                f"the network on the lent NNA submodules needs {lent_gbps:.3f} GB/s of DRAM, not "
                f"below the channel's dram.gbps={d.gbps}: the stereo pair would get no slot; "
                "lower its fps, widen the channel or lend more submodules (less spill)")
        add("lent", math.ceil(x * base / (1 - x) - 1e-9), 0.0,
            "the network on the lent NNA submodules (nna.lent_network)")
    plan = DramPlan(slot_fs, round(d.latency_ns * 1e6), sum(c.count for c in clients),
                    tuple(clients), d.burst_bytes, px, d.read_prefetch_bursts, wpb,
                    d.write_buffer_bursts)
    if camera_writes:
        need = camera_hz * line_share  # bytes per second per camera within its lines
        got = px * 1e15 / plan.round_fs
        if got < need:
            raise ConfigError(
                f"the DRAM channel writes {got / 1e9:.3f} GB/s per camera into the frame "
                f"buffers but a camera sends {need / 1e9:.3f} GB/s in its lines: raise "
                "dram.gbps or lower the other clients' load (dram.spill, nna.lent_network)")
    return plan
