"""Census transform: the chip's hand-crafted per-pixel binary descriptor.

Definition (the one every layer -- reference, kernel, clocked block -- must reproduce bit for bit)

* Window ``(w, h)``: width and height, both odd, in 1..15. Stride ``s`` in 1..4 is the sampling
  step inside the window (``s = 2`` is the "sparse census").
* Sample grid: ``dx = -(w // 2) + i * s`` for ``i = 0, 1, ...`` while ``dx <= w // 2``, and the
  same for ``dy`` with ``h``. The grid is enumerated in row-major order (``dy`` outer, ``dx``
  inner); the centre ``(0, 0)`` is never compared. When ``s`` does not divide ``w - 1`` (or
  ``h - 1``) the grid is not symmetric about the centre (e.g. 9 wide with stride 3 samples
  ``dx = -4, -1, 2``); the definition still holds as written.
* ``kind="plain"``: one comparison per grid offset ``o != (0, 0)``:
  ``bit = 1 if I(p + o) > I(p) else 0``.
* ``kind="symmetric"`` (centre-symmetric census): one comparison per grid offset ``o`` that comes
  *before* the centre in row-major order, i.e. ``dy < 0``, or ``dy == 0 and dx < 0``:
  ``bit = 1 if I(p + o) > I(p - o) else 0`` (the pixel against its mirror through the centre,
  sampled even where the mirror is not itself a grid point).
* Comparisons are strict, so a flat image gives all-zero descriptors, and adding a constant to an
  image (without clipping) leaves every descriptor unchanged.

Bit order: LSB first. Bit ``i`` of the descriptor is comparison ``i`` in the row-major order above,
so bit 0 compares the top-left sample of the grid. :func:`census_offsets` lists the offsets in
exactly that order.

Border policy: replicate. Coordinates outside the image are clamped into it
(``I(y, x) = img[clamp(y, 0, H-1), clamp(x, 0, W-1)]``); every descriptor of the chip (census and
the NNA convolution) uses this same policy.

Output: one descriptor per pixel, ``uint32`` when the descriptor has at most 32 bits, else
``uint64``. More than 64 bits (e.g. plain 9x9 = 80 bits) is a :class:`~core.errors.ConfigError`.
"""

from __future__ import annotations

import numpy as np

from stereosim.core.census_layout import comparison_offsets
from stereosim.core.errors import ConfigError, InputError
from stereosim.core.kernel_cache import njit

KINDS = ("plain", "symmetric")
MAX_WINDOW = 15
MAX_STRIDE = 4
MAX_BITS = 64


def _check_params(window, kind, stride) -> tuple[int, int, str, int]:
    """Validate the census parameters; return ``(w, h, kind, stride)`` as plain Python values."""
    try:
        w, h = window
    except (TypeError, ValueError):
        raise ConfigError(
            f"census window must be a pair (width, height) of odd ints, got {window!r}"
        ) from None
    for name, v in (("width", w), ("height", h)):
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool):
            raise ConfigError(f"census window {name} must be an int, got {v!r}")
        if not (1 <= v <= MAX_WINDOW and v % 2 == 1):
            raise ConfigError(
                f"census window {name} must be odd and in 1..{MAX_WINDOW}, got {v} "
                f"(window {tuple(window)!r})"
            )
    if kind not in KINDS:
        raise ConfigError(f"census kind must be one of {KINDS}, got {kind!r}")
    if not isinstance(stride, (int, np.integer)) or isinstance(stride, bool):
        raise ConfigError(f"census stride must be an int in 1..{MAX_STRIDE}, got {stride!r}")
    if not 1 <= stride <= MAX_STRIDE:
        raise ConfigError(f"census stride must be in 1..{MAX_STRIDE}, got {stride}")
    return int(w), int(h), str(kind), int(stride)


def census_offsets(
    window=(9, 7), kind: str = "symmetric", stride: int = 1
) -> list[tuple[int, int]]:
    """The ``(dx, dy)`` offsets compared by the census, in bit order (bit i = entry i).

    For ``plain`` bit i compares ``I(p + o_i)`` with ``I(p)``; for ``symmetric`` it compares
    ``I(p + o_i)`` with ``I(p - o_i)``. Raises :class:`ConfigError` for bad parameters or when the
    descriptor would have no bits or more than 64.
    """
    w, h, kind, stride = _check_params(window, kind, stride)
    offsets = comparison_offsets(w, h, kind, stride)
    n_bits = len(offsets)
    if n_bits == 0:
        raise ConfigError(
            f"census window {w}x{h} with stride {stride} compares nothing (0 bits); "
            "use a window of at least 3 in one direction"
        )
    if n_bits > MAX_BITS:
        hints = []
        if kind == "plain":
            n_sym = len(comparison_offsets(w, h, "symmetric", stride))
            if n_sym <= MAX_BITS:
                hints.append(f"kind='symmetric' ({n_sym} bits)")
        for s in range(stride + 1, MAX_STRIDE + 1):
            n_s = len(comparison_offsets(w, h, kind, s))
            if n_s <= MAX_BITS:
                hints.append(f"stride={s} ({n_s} bits)")
                break
        hints.append("a smaller window")
        raise ConfigError(
            f"census window {w}x{h} {kind} with stride {stride} gives {n_bits} bits, more than "
            f"the {MAX_BITS} a descriptor holds; use " + " or ".join(hints)
        )
    return offsets


def census_bits(window=(9, 7), kind: str = "symmetric", stride: int = 1) -> int:
    """Number of bits of the census descriptor (1..64); :class:`ConfigError` if not storable."""
    return len(census_offsets(window, kind, stride))


def census_dtype(window=(9, 7), kind: str = "symmetric", stride: int = 1) -> np.dtype:
    """Output dtype of the census: uint32 up to 32 bits, else uint64."""
    return np.dtype(np.uint32 if census_bits(window, kind, stride) <= 32 else np.uint64)


def as_image_u8(img, what: str = "image") -> np.ndarray:
    """Validate a grey image: 2-D uint8, at least 1x1; return it C-contiguous.

    Shared by every descriptor of the package; raises :class:`InputError` with a one-line fix.
    """
    if not isinstance(img, np.ndarray):
        raise InputError(
            f"{what} must be a numpy array, got {type(img).__name__}; "
            "pass np.asarray(img, dtype=np.uint8)"
        )
    if img.ndim != 2:
        raise InputError(
            f"{what} must be 2-D (H, W) grey, got shape {img.shape}; "
            "convert colour images with cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)"
        )
    if img.dtype != np.uint8:
        raise InputError(
            f"{what} must be uint8, got {img.dtype}; "
            "scale to 0..255 and convert with img.astype(np.uint8)"
        )
    if img.shape[0] < 1 or img.shape[1] < 1:
        raise InputError(f"{what} must be at least 1x1, got shape {img.shape}")
    return np.ascontiguousarray(img)


def census_ref(img: np.ndarray, window=(9, 7), kind: str = "symmetric", stride: int = 1):
    """Naive census, written as the definition in the module docstring reads.

    Plain Python loops over pixels and comparisons with explicit coordinate clamping; slow, for
    tests and as the specification of :func:`census`.
    """
    img = as_image_u8(img)
    offsets = census_offsets(window, kind, stride)
    height, width = img.shape
    pixels = img.tolist()

    def sample(y: int, x: int) -> int:
        # Replicate border: clamp the coordinates into the image.
        return pixels[min(max(y, 0), height - 1)][min(max(x, 0), width - 1)]

    out = np.zeros((height, width), dtype=census_dtype(window, kind, stride))
    for y in range(height):
        for x in range(width):
            descriptor = 0
            for bit, (dx, dy) in enumerate(offsets):
                if kind == "plain":
                    other = sample(y, x)
                else:
                    other = sample(y - dy, x - dx)
                if sample(y + dy, x + dx) > other:
                    descriptor |= 1 << bit
            out[y, x] = descriptor
    return out


@njit(cache=True)
def _census_kernel(padded, rc_a, rc_b, masks, out):
    """Census on a replicate-padded image.

    ``padded`` is uint8 (H + 2*ry, W + 2*rx); ``rc_a[k]`` and ``rc_b[k]`` are the (row, col)
    shifts in ``padded`` of the two samples of comparison k; ``masks[k] = 1 << k`` in the output
    dtype; ``out`` is (H, W). Row by row, comparison by comparison, so the innermost loop runs
    along a row of contiguous bytes and vectorises.
    """
    height, width = out.shape
    n_bits = rc_a.shape[0]
    acc = np.zeros(width, dtype=out.dtype)
    zero = acc[0]
    for y in range(height):
        acc[:] = zero
        for k in range(n_bits):
            row_a = padded[y + rc_a[k, 0], rc_a[k, 1] : rc_a[k, 1] + width]
            row_b = padded[y + rc_b[k, 0], rc_b[k, 1] : rc_b[k, 1] + width]
            mask = masks[k]
            for x in range(width):
                acc[x] |= mask if row_a[x] > row_b[x] else zero
        out[y, :] = acc


def census(img: np.ndarray, window=(9, 7), kind: str = "symmetric", stride: int = 1) -> np.ndarray:
    """Census descriptor of every pixel of a uint8 image (see the module docstring).

    Returns an (H, W) array, uint32 for descriptors of at most 32 bits, else uint64. Raises
    :class:`InputError` for an unusable image and :class:`ConfigError` for bad parameters.
    """
    img = as_image_u8(img)
    offsets = census_offsets(window, kind, stride)
    dtype = census_dtype(window, kind, stride)
    w, h = int(window[0]), int(window[1])
    rx, ry = w // 2, h // 2
    # Pad once; every sample of the window (and every mirror) lies within rx, ry of the centre.
    padded = np.pad(img, ((ry, ry), (rx, rx)), mode="edge")
    rc_a = np.array([(ry + dy, rx + dx) for dx, dy in offsets], dtype=np.int64)
    if kind == "plain":
        rc_b = np.array([(ry, rx)] * len(offsets), dtype=np.int64)
    else:
        rc_b = np.array([(ry - dy, rx - dx) for dx, dy in offsets], dtype=np.int64)
    masks = np.array([1 << k for k in range(len(offsets))], dtype=dtype)
    out = np.empty(img.shape, dtype=dtype)
    _census_kernel(padded, rc_a, rc_b, masks, out)
    return out
