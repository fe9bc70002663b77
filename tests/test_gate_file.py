"""The gate's model-file section: written and loaded back to the same p-values, a damaged field refused in one line
naming it, and a file without the section loading (predict then says once that nothing is gated)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from roughsense.errors import ModelFileError
from roughsense.model.contact_gate import fit_gate
from roughsense.model.gate_file import KEY, gate_section, loaded_gate

NAMES = ("peak_over_noise", "contrast_dn", "coherence")


def _gate():
    rng = np.random.default_rng(0)
    values = np.column_stack([np.exp(rng.normal(3, 0.3, 40)), np.exp(rng.normal(4, 0.2, 40)),
                              rng.uniform(0.4, 0.8, 40)])
    return fit_gate(values, NAMES, np.repeat([f"S{i}" for i in range(8)], 5), seed=0), values


def test_the_section_round_trips_through_json():
    gate, values = _gate()
    stored = json.loads(json.dumps(gate_section(gate)))
    loaded = loaded_gate(stored, None)
    np.testing.assert_array_equal(loaded.p_values(values), gate.p_values(values))
    assert loaded.names == NAMES and loaded.alpha == 0.01
    assert loaded_gate(None, None) is None  # a file written before the gate


@pytest.mark.parametrize(("field", "value", "message"), [
    ("descriptors", ["peak_over_noise", "colour", "coherence"], "descriptors must name"),
    ("alpha", 2.0, "alpha must be"),
    ("calibration_folds", [99] * 40, "calibration_folds must be detector numbers"),
    ("scale", [1.0, 0.0, 1.0], "scale must be positive"),
    ("precisions", "x", "precisions must be"),
])
def test_a_damaged_field_is_refused_naming_it(field, value, message):
    gate, _ = _gate()
    stored = gate_section(gate)
    stored[field] = value
    with pytest.raises(ModelFileError, match=message) as raised:
        loaded_gate(stored, None)
    assert f"training.{KEY}" in str(raised.value)
