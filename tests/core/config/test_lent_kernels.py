"""The lent network's file (nna.lent_network, a TOML file, not a weight file) bounds every
layer's kernel, not only the first's: a later layer of 17 or 65 is one line naming it."""

import pytest

from stereosim.core.config import load_config
from stereosim.core.config.lent import read_lent_network
from stereosim.core.errors import ConfigError


@pytest.mark.parametrize("kernel", [17, 65])
@pytest.mark.parametrize("layer", [0, 2])
def test_every_layers_kernel_is_bounded(tmp_path, lent_toml, layer, kernel):
    shapes = [[3, 1, 4, 1], [3, 4, 4, 1], [3, 4, 8, 1]]
    shapes[layer][0] = kernel
    path = lent_toml(tmp_path / "lent.toml", [tuple(s) for s in shapes])
    pattern = rf"layer\[{layer}\]\.kernel must be in \[1, 15\]; got {kernel}"
    with pytest.raises(ConfigError, match=pattern):
        read_lent_network(path)
    with pytest.raises(ConfigError, match=pattern):
        load_config(overrides={"nna.lent_submodules": 1, "nna.lent_network": path})
