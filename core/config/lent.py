"""The network run on the lent NNA submodules (``nna.lent_network``): a TOML file read and
checked in full where the configuration is loaded, one line for each mistake naming the file
and the field.

The file::

    about = "what the network is"       # optional
    fps = 30.0                          # its frame rate target, or "max": as fast as it can

    [input]
    width = 224
    height = 224
    channels = 3

    [[layer]]                           # one table per convolution layer, in order
    kernel = 3                          # odd, K x K
    channels_in = 3                     # the input's channels, then the layer before's out
    channels_out = 16
    stride = 2                          # 1..4; "same" padding: ceil(N / stride) outputs

Layer l's input is layer l - 1's output; its size follows the strides
(:func:`nna.geometry.strided_size` applies the rule in the plan; the file only states the
layers).
"""

from __future__ import annotations

from dataclasses import dataclass

from stereosim.core.config.files import read_toml
from stereosim.core.errors import ConfigError
from stereosim.core.outputs import path_text

# field -> (lo, hi) of the integers a file may give
_INPUT = {"width": (1, 8192), "height": (1, 8192), "channels": (1, 4096)}
_LAYER = {"kernel": (1, 15), "channels_in": (1, 4096), "channels_out": (1, 4096),
          "stride": (1, 4)}
_TOP = ("about", "fps", "input", "layer")
MAX_LAYERS = 64
MAX_FPS = 1e7


@dataclass(frozen=True)
class LentLayer:
    """A convolution layer of the lent network: K x K kernel, C_in -> C_out channels, stride."""

    kernel: int
    channels_in: int
    channels_out: int
    stride: int

    @property
    def macs_per_pixel(self) -> int:
        """Multiply-accumulates of one output pixel: K^2 C_in C_out."""
        return self.kernel * self.kernel * self.channels_in * self.channels_out


@dataclass(frozen=True)
class LentNetwork:
    """The lent network of a file: its input (width, height, channels), its frame rate target
    (``fps``; None: as fast as it can) and its layers."""

    path: str
    about: str
    width: int
    height: int
    channels: int
    fps: float | None
    layers: tuple[LentLayer, ...]


def _integer(where: str, field: str, value, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(f"{where}: {field} must be an integer; got {value!r}")
    if not lo <= value <= hi:
        raise ConfigError(f"{where}: {field} must be in [{lo}, {hi}]; got {value}")
    return value


def _table(where: str, name: str, value, keys) -> dict:
    if not isinstance(value, dict):
        raise ConfigError(f"{where}: {name} must be a table ([{name}])")
    for key in value:
        if key not in keys:
            raise ConfigError(f"{where}: unknown key {name}.{key} (known: "
                              f"{', '.join(f'{name}.{k}' for k in keys)})")
    for key in keys:
        if key not in value:
            raise ConfigError(f"{where}: {name}.{key} is missing")
    return value


def _fps(where: str, value) -> float | None:
    if value == "max":
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            0 < value <= MAX_FPS):
        raise ConfigError(f"{where}: fps must be a number in (0, {MAX_FPS:g}] or \"max\" (as "
                          f"fast as it can); got {value!r}")
    return float(value)


def read_lent_network(path) -> LentNetwork:
    """The lent network of the TOML file at ``path``, every field checked (module docstring);
    a mistake raises :class:`ConfigError` with one line naming the file and the field."""
    where = f"lent network {path_text(path)}"
    raw = read_toml(path, "lent network")
    for key in raw:
        if key not in _TOP:
            raise ConfigError(f"{where}: unknown key {key} (known: {', '.join(_TOP)})")
    for key in ("fps", "input", "layer"):
        if key not in raw:
            raise ConfigError(f"{where}: {key} is missing" + (
                " (give one [[layer]] table per layer)" if key == "layer" else ""))
    about = raw.get("about", "")
    if not isinstance(about, str):
        raise ConfigError(f"{where}: about must be text; got {about!r}")
    fps = _fps(where, raw["fps"])
    inp = _table(where, "input", raw["input"], _INPUT)
    size = {k: _integer(where, f"input.{k}", inp[k], *_INPUT[k]) for k in _INPUT}
    layers_raw = raw["layer"]
    if not isinstance(layers_raw, list) or not 1 <= len(layers_raw) <= MAX_LAYERS:
        raise ConfigError(f"{where}: layer must be 1 to {MAX_LAYERS} [[layer]] tables")
    layers = []
    channels = size["channels"]
    for i, body in enumerate(layers_raw):
        name = f"layer[{i}]"
        body = _table(where, name, body, _LAYER)
        v = {k: _integer(where, f"{name}.{k}", body[k], *_LAYER[k]) for k in _LAYER}
        if v["kernel"] % 2 == 0:
            raise ConfigError(f"{where}: {name}.kernel must be odd; got {v['kernel']}")
        if v["channels_in"] != channels:
            before = "input.channels" if i == 0 else f"layer[{i - 1}].channels_out"
            raise ConfigError(f"{where}: {name}.channels_in = {v['channels_in']} must equal "
                              f"{before} = {channels}")
        layers.append(LentLayer(**v))
        channels = v["channels_out"]
    return LentNetwork(path=str(path), about=about, fps=fps, layers=tuple(layers), **size)
