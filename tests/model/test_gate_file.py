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
    ("descriptors", ["peak_over_noise", "colour", "coherence"], r"descriptors\[1\]: expected one of"),
    ("alpha", 2.0, "alpha: expected a number above 0 and at most 0.5"),
    ("calibration_folds", [99] * 40, "calibration_folds: must be detector numbers"),
    ("scale", [1.0, 0.0, 1.0], r"scale\[1\]: expected a number above 0"),
    ("precisions", "x", "precisions: expected an array"),
    ("center", [0.0, 1.0], r"center: must have shape \[3\]"),
    ("precisions", [[[1.0, 2.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]] * 8, "precisions: must be symmetric"),
])
def test_a_damaged_field_is_refused_naming_it(field, value, message):
    gate, _ = _gate()
    stored = gate_section(gate)
    stored[field] = value
    with pytest.raises(ModelFileError, match=message) as raised:
        loaded_gate(stored, None)
    assert f"training.{KEY}" in str(raised.value)


def ungated(path):
    """A model file as written before the gate (its section removed, the checksum recomputed): for tests of other
    features that feed a model images unlike its training presses on purpose (drawings, other scales)."""
    from roughsense.model.modelfile import _digest

    document = json.loads(path.read_text())
    document["training"].pop(KEY, None)
    document["sha256"] = _digest(document)
    path.write_text(json.dumps(document))
    return path


def test_a_file_without_the_section_predicts_and_says_so_once(tmp_path):
    import warnings

    import roughsense as rs
    from roughsense.model.press_gate import NO_GATE_LINE

    rng = np.random.default_rng(0)
    spectrum = rs.SpatialSpectrum().fit()
    images = [np.tile(128 + 100 * np.sign(np.sin(2 * np.pi * np.arange(1920) / 34.9 / p)), (320, 1))
              + rng.normal(0, 5, (320, 1920)) for p in (2.0, 3.0, 4.0, 5.0)]
    X = spectrum.transform([np.clip(i, 0, 255).astype(np.uint8) for i in images])
    law = rs.PeakPowerLaw(freq_per_mm=spectrum.freq_per_mm_).fit(X, np.array([2.0, 3.0, 4.0, 5.0]) / 3)
    from roughsense.model.modelfile import save_model

    path = save_model(tmp_path / "law.json", law, training={"reference_specimen": "R3"},
                      feature_definition={"spectrum": spectrum.feature_definition(), "conditions": ["2N"]})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        table = rs.predict(ungated(path), [np.clip(images[0], 0, 255).astype(np.uint8)])
    assert [str(w.message) for w in caught].count(NO_GATE_LINE) == 1
    assert not table["withheld"].any() and table["contact_p"].isna().all()
