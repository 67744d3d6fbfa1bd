"""The settings of a training run of the learned descriptor, and the networks it can train.

Thirteen variants, all with 32 output channels (one descriptor bit each) but the two 64-bit ones,
and all with a 9x9 receptive field but the last (:func:`receptive_field`):
``mccnn4`` (four 3x3 convolutions, channels 1, 32, 32, 32, 32: MC-CNN-fast), ``mccnn4-slim``
(four 3x3 convolutions, channels 1, 4, 4, 8, 32), ``single9x9`` (one 9x9 convolution, 1 -> 32:
the network the chip ships), ``mixed5x5`` (a 5x5 convolution 1 -> 8, then 3x3 ones 8 -> 16
-> 32: 5,960 MACs per pixel, between the slim and the full four-layer network) and ``mccnn4-mid``
(four 3x3 convolutions, channels 1, 16, 16, 32, 32: 16,272 MACs per pixel, inside the 720p
30 fps budget of 24,000 that the full network exceeds), and two wider candidates inside that
budget: ``mccnn4-wide`` (channels 1, 24, 24, 32, 32: 21,528 MACs per pixel) and
``mixed5x5-wide`` (a 5x5 convolution 1 -> 32, then two 3x3 ones 32 -> 32: 19,232), and three
more shapes of that budget: ``mixed5x5-40`` (5x5 1 -> 40, 3x3 40 -> 32, 3x3 32 -> 32: 21,736),
``double5x5`` (5x5 1 -> 24, 5x5 24 -> 32: 19,800) and ``mixed7x7`` (7x7 1 -> 32, 3x3 32 -> 32:
10,784, inside the 60 fps budget of about 12,000). Two give 64-bit descriptors (uint64 words,
the SVA's widest): ``single9x9-64`` (one 9x9 convolution 1 -> 64: 5,184 MACs) and
``mixed5x5-64`` (5x5 1 -> 16, 3x3 16 -> 24, 3x3 24 -> 64: 17,680). ``mixed5x5-rf11`` reads an
11x11 window (5x5 1 -> 16, 5x5 16 -> 24, 3x3 24 -> 32: 16,912 MACs, inside the 30 fps budget).
:class:`TrainConfig`
checks every setting when it is built (one line naming it).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from stereosim.core.config import SvaConfig
from stereosim.core.errors import ConfigError

# (C_in, C_out, K) per layer
VARIANTS = {
    "mccnn4": ((1, 32, 3), (32, 32, 3), (32, 32, 3), (32, 32, 3)),
    "mccnn4-slim": ((1, 4, 3), (4, 4, 3), (4, 8, 3), (8, 32, 3)),
    "single9x9": ((1, 32, 9),),
    "mixed5x5": ((1, 8, 5), (8, 16, 3), (16, 32, 3)),
    "mccnn4-mid": ((1, 16, 3), (16, 16, 3), (16, 32, 3), (32, 32, 3)),
    "mccnn4-wide": ((1, 24, 3), (24, 24, 3), (24, 32, 3), (32, 32, 3)),
    "mixed5x5-wide": ((1, 32, 5), (32, 32, 3), (32, 32, 3)),
    "mixed5x5-40": ((1, 40, 5), (40, 32, 3), (32, 32, 3)),
    "mixed7x7": ((1, 32, 7), (32, 32, 3)),
    "double5x5": ((1, 24, 5), (24, 32, 5)),
    "single9x9-64": ((1, 64, 9),),
    "mixed5x5-64": ((1, 16, 5), (16, 24, 3), (24, 64, 3)),
    "mixed5x5-rf11": ((1, 16, 5), (16, 24, 5), (24, 32, 3)),
}


def receptive_field(variant: str) -> int:
    """Side of the input window one output pixel of ``variant`` reads: 1 + sum (K_l - 1)."""
    return 1 + sum(k - 1 for _, _, k in VARIANTS[variant])

def _sva_rule(name: str) -> dict:
    return next(f.metadata for f in dataclasses.fields(SvaConfig) if f.name == name)


def box_range() -> tuple[int, int]:
    """The windows ``box`` and ``aggregate`` may take: they stand in the loss for the chip's box
    filter, so sva.box_size's declared range (odd)."""
    rule = _sva_rule("box_size")
    return rule["lo"], rule["hi"]


def max_disparities() -> int:
    """The most candidate disparities a run may score: the chip's widest range
    (sva.disparities)."""
    return max(_sva_rule("disparities")["choices"])


SIMILARITIES = ("cosine", "tanh", "both")
OBJECTIVES = ("curve", "triplet")
DEVICES = ("cpu", "cuda")  # where torch trains (nna.trainrun.training_device)


@dataclass(frozen=True, slots=True, kw_only=True)
class TrainConfig:
    """Settings of one training run (all recorded in the output file)."""

    variant: str = "single9x9"
    objective: str = "curve"
    epochs: int = 20
    steps_per_epoch: int = 1000
    lr: float = 0.004
    seed: int = 0
    # objective "curve": strips of the reference view against every candidate disparity
    strips: int = 32
    strip_width: int = 64
    disparities: int = 96
    box: int = 5
    temperature: float = 1.0
    scale_start: float = 1.0
    scale_end: float = 12.0
    sign_fraction: float = 0.3
    balance: float = 1.0
    decorrelate: float = 0.5
    # objective "triplet": one positive and one negative right patch per left pixel
    batch: int = 256
    pos_offset: float = 0.5
    neg_low: float = 1.5
    neg_high: float = 6.0
    margin: float = 0.2
    similarity: str = "tanh"
    aggregate: int = 1
    gain: float = 0.2
    offset: float = 20.0
    noise_max: float = 2.0
    # more of what differs between two cameras (nna.augment; 0 = off)
    gamma: float = 0.0
    shot_noise: float = 0.0
    blur_max: float = 0.0
    vshift_max: float = 0.0
    input_offset: int = 128
    input_scale: float = 1.0 / 64.0
    threads: int = 0  # torch CPU threads; 0 = auto (nna.trainrun.pick_threads)
    # where torch trains: "cpu", or "cuda" (a GPU; other weights than the CPU's, same recipe)
    device: str = "cpu"
    # quantisation-aware fine-tuning (nna.trainqat): the float model it starts from, "" = none
    qat: str = ""

    def __post_init__(self):
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.type in ("int", "float") and (
                isinstance(value, bool) or not isinstance(value, (int, float))
            ):
                raise ConfigError(f"{f.name} must be a number, got {_shown(value)}")
            if f.type == "int" and not isinstance(value, int):
                raise ConfigError(f"{f.name} must be a whole number, got {_shown(value)}")
            if f.type == "float" and not (-math.inf < _as_float(value) < math.inf):
                raise ConfigError(f"{f.name} must be a finite number, got {_shown(value)}")
            if f.type == "str" and not isinstance(value, str):
                raise ConfigError(f"{f.name} must be text, got {_shown(value)}")
        if self.variant not in VARIANTS:
            raise ConfigError(
                f"unknown variant {_shown(self.variant)}; choose one of {', '.join(VARIANTS)}"
            )
        if self.objective not in OBJECTIVES:
            raise ConfigError(
                f"unknown objective {_shown(self.objective)}; choose one of {', '.join(OBJECTIVES)}"
            )
        if self.similarity not in SIMILARITIES:
            raise ConfigError(
                f"unknown similarity {_shown(self.similarity)}; choose one of "
                f"{', '.join(SIMILARITIES)}"
            )
        lo, hi = box_range()
        for name in ("aggregate", "box"):
            if getattr(self, name) < lo or getattr(self, name) % 2 == 0:
                raise ConfigError(f"{name} must be odd and >= {lo}, got "
                                  f"{_shown(getattr(self, name))}")
            if getattr(self, name) > hi:
                raise ConfigError(f"{name} must be at most {hi} (sva.box_size's range), got "
                                  f"{_shown(getattr(self, name))}")
        for name in ("epochs", "steps_per_epoch", "batch", "strips", "strip_width"):
            if getattr(self, name) < 1:
                raise ConfigError(f"{name} must be at least 1, got {_shown(getattr(self, name))}")
        if self.device not in DEVICES:
            raise ConfigError(f"device must be one of {', '.join(DEVICES)}, got "
                              f"{_shown(self.device)}")
        if self.threads < 0:
            raise ConfigError(f"threads must be 0 (auto) or more, got {_shown(self.threads)}")
        if not 0 <= self.pos_offset < self.neg_low <= self.neg_high:
            raise ConfigError(
                "offsets must satisfy 0 <= pos_offset < neg_low <= neg_high, got "
                f"{self.pos_offset}, {self.neg_low}, {self.neg_high}"
            )
        if not 0 <= self.input_offset <= 255 or not self.input_scale > 0:
            raise ConfigError("input_offset must be in 0..255 and input_scale positive")
        if self.lr <= 0 or min(self.margin, self.gain, self.offset, self.noise_max, self.gamma,
                               self.shot_noise, self.blur_max, self.vshift_max) < 0:
            raise ConfigError("lr must be positive; margin, gain, offset, noise_max, gamma, "
                              "shot_noise, blur_max and vshift_max non-negative")
        if not 2 <= self.disparities <= max_disparities():
            raise ConfigError(f"disparities must be in 2..{max_disparities()} (the chip's widest "
                              f"range, sva.disparities), got {_shown(self.disparities)}")
        if not (self.temperature > 0 and 0 < self.scale_start <= self.scale_end):
            raise ConfigError(
                "temperature must be positive and 0 < scale_start <= scale_end, got "
                f"{self.temperature}, {self.scale_start}, {self.scale_end}"
            )
        if not 0 <= self.sign_fraction <= 1 or min(self.balance, self.decorrelate) < 0:
            raise ConfigError("sign_fraction must be in [0, 1]; balance, decorrelate >= 0")
        # the augmentation's ranges (nna.augment) on the 8-bit grey scale: an offset or a noise
        # sigma beyond 255 grey levels leaves nothing but clipping, a gain above 1 may be
        # negative (an inverted view), a gamma above 1 raises to powers beyond e^+-1
        if max(self.offset, self.noise_max, self.shot_noise) > 255 or max(self.gain,
                                                                          self.gamma) > 1:
            raise ConfigError(
                "offset, noise_max and shot_noise must be at most 255 grey levels and gain and "
                f"gamma at most 1, got {self.offset}, {self.noise_max}, {self.shot_noise}, "
                f"{self.gain}, {self.gamma}")
        if max(self.blur_max, self.vshift_max) > self.crop_rows:
            raise ConfigError(
                f"blur_max and vshift_max must be at most {self.crop_rows} px, the rows a "
                "training sample cuts from a view (a wider defocus or misalignment leaves "
                f"nothing of the crop to learn from), got {self.blur_max}, {self.vshift_max}")

    @property
    def crop_rows(self) -> int:
        """Rows a training sample cuts from a view: the variant's receptive field grown by the
        loss's window (``box`` for the curve objective, ``aggregate`` for the triplet)."""
        window = self.box if self.objective == "curve" else self.aggregate
        return receptive_field(self.variant) + window - 1


def _as_float(value) -> float:
    """``value`` as a float; an integer too large for one is infinite."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


def _shown(value) -> str:
    """``repr(value)`` for a one-line message, cut short (a value from a crafted file may be a
    4,000-digit number or a long list)."""
    text = repr(value)
    return text if len(text) <= 40 else f"{text[:37]}..."
