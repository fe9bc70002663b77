"""io/protocol.py: a measured force is assigned the nearest of the protocol's nominal forces, or refused."""
from __future__ import annotations

import pandas as pd
import pytest

from roughsense.errors import InputError
from roughsense.io.protocol import assign_nominal_forces


def test_nominal_force_is_nearest_protocol_force():
    manifest = pd.DataFrame({"force_n": [0.93, 2.08, 3.2]})
    out = assign_nominal_forces(manifest, (1.0, 2.0, 3.0))
    assert list(out["condition"]) == ["1N", "2N", "3N"]
    with pytest.raises(InputError):
        assign_nominal_forces(pd.DataFrame({"force_n": [4.2]}), (1.0, 2.0, 3.0))
