"""docs/parameters.md lists every declared node parameter with its default."""

from __future__ import annotations

import pytest
from support.paths import REPO

from gnss_driver.node import PARAMETERS as GNSS_PARAMETERS
from imu400cc_driver.node import PARAMETERS as IMU_PARAMETERS
from ins_fusion.core.settings.params import PARAMETERS as FUSION_PARAMETERS
from ntrip_client.node import PARAMETERS as NTRIP_PARAMETERS

NODES = {
    "imu400cc_node": IMU_PARAMETERS,
    "gnss_node": GNSS_PARAMETERS,
    "ntrip_node": NTRIP_PARAMETERS,
    "ins_fusion_node": FUSION_PARAMETERS,
}


@pytest.mark.parametrize("node", sorted(NODES))
def test_every_parameter_is_documented_with_its_default(node):
    text = (REPO / "docs" / "parameters.md").read_text()
    section = text.split(f"## {node}\n", 1)[1].split("\n## ", 1)[0]
    for spec in NODES[node]:
        default = f"`{spec.default}`" if isinstance(spec.default, str) else str(spec.default)
        assert f"| `{spec.name}` | {default} |" in section, spec.name
        assert spec.description in section, spec.name
