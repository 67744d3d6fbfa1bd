"""The one configuration object of the chip.

Frozen dataclasses, one per block, nested in :class:`ChipConfig`. Every field declares its type,
its legal range or choices and a one-line help text; :func:`load_config` builds the object from
the defaults, an optional TOML file and dotted-key overrides, and rejects unknown keys and bad
values with the key's dotted name. ``stereosim config show`` prints the result as TOML.

The package's modules, bottom up: :mod:`~core.config.widths` (the rule of the automatic register
widths), :mod:`~core.config.schema` (the declarations), :mod:`~core.config.files` (reading a TOML
file), :mod:`~core.config.lent` (the file of the network on lent NNA submodules),
:mod:`~core.config.check` (the checks, run once where a configuration enters),
:mod:`~core.config.loader` (TOML file and overrides) and :mod:`~core.config.writer` (TOML out,
diffs). Their public names are imported from here.
"""

from stereosim.core.config.check import check_config, check_section
from stereosim.core.config.files import read_toml
from stereosim.core.config.lent import LentLayer, LentNetwork, read_lent_network
from stereosim.core.config.loader import (
    descriptor_width,
    keys_set,
    layer_notes,
    load_config,
    parse_set_options,
)
from stereosim.core.config.schema import (
    AUTO_BUDGET_FACTOR,
    DEFAULT_DESCRIPTOR,
    DESCRIPTOR_DEFAULTS,
    LEGAL_DISPARITIES,
    PATH_BITS_MAX,
    PENALTY_MAX,
    RETIRED,
    SECTIONS,
    SUM_BITS_MAX,
    CensusConfig,
    ChipConfig,
    ClockConfig,
    CnnConfig,
    DramConfig,
    FifoConfig,
    NnaConfig,
    PowerConfig,
    SimConfig,
    SourceConfig,
    SvaConfig,
    param,
)
from stereosim.core.config.widths import CNN_BITS, sgm_widths
from stereosim.core.config.writer import config_diff, config_to_dict, config_to_toml

__all__ = [
    "AUTO_BUDGET_FACTOR", "CNN_BITS", "DEFAULT_DESCRIPTOR", "DESCRIPTOR_DEFAULTS",
    "LEGAL_DISPARITIES", "PATH_BITS_MAX", "PENALTY_MAX", "SECTIONS", "SUM_BITS_MAX",
    "CensusConfig", "ChipConfig", "ClockConfig", "CnnConfig", "DramConfig", "FifoConfig",
    "LentLayer", "LentNetwork", "NnaConfig", "PowerConfig", "RETIRED", "SimConfig",
    "SourceConfig", "SvaConfig",
    "check_config", "check_section", "config_diff", "config_to_dict", "config_to_toml",
    "descriptor_width", "keys_set", "layer_notes", "load_config", "param", "parse_set_options",
    "read_lent_network", "read_toml", "sgm_widths",
]
