"""model/predict_table.py: one prediction carries one 90 % interval, named by its method (issue 46: with --study a
press's plain jackknife stood in pi90_low/pi90_high, the README's "jackknife+" columns, beside its surface's
jackknife+, so nobody could tell the interval with a guarantee from the one without)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from roughsense.model.model_intervals import PLAIN_METHOD
from roughsense.model.predict_table import PREDICTION_COLUMNS, prediction_table
from roughsense.model.scoring import Scores

PLUS = "jackknife+ over specimens (14), residuals of 3-press surfaces"
LOADED = SimpleNamespace(conditions=["1N"], family="peak-law", training={"reference_specimen": "R3"},
                         model_file_=SimpleNamespace(features={"spectrum": {"px_per_mm": 20.0}}))


def _table(method, surface_method=None):
    surfaces = None if surface_method is None else ["s", "s", "s"]
    trials = SimpleNamespace(groups=[("a.png",), ("b.png",), ("c.png",)], override=None, surfaces=surfaces, meta=None,
                             pad="smooth", condition="1N")
    roughness = np.array([1.0, 1.2, 1.4])
    grouped = {} if surface_method is None else {
        "surface_roughness": np.full(3, 1.2), "surface_low": np.full(3, 0.8), "surface_high": np.full(3, 1.8),
        "surface_method": [surface_method] * 3}
    scores = Scores(roughness, roughness / 1.5, roughness * 1.5, [""] * 3, method=[method] * 3, **grouped)
    return prediction_table(LOADED, trials, scores)


def _intervals(table) -> set[str]:
    return {c for c in table.columns if "pi90" in c or "jackknife90" in c}


def test_the_jackknife_plus_is_pi90_and_the_plain_jackknife_never_is():
    alone = _table(PLUS)  # a press read alone: the jackknife+ of one-press surfaces
    assert _intervals(alone) == {"pi90_low", "pi90_high", "pi90_method"} and set(alone["pi90_method"]) == {PLUS}
    grouped = _table(PLAIN_METHOD, PLUS)  # --study: each press's plain jackknife, its surface's jackknife+
    assert _intervals(grouped) == {"jackknife90_low", "jackknife90_high", "surface_pi90_low", "surface_pi90_high",
                                   "surface_pi90_method"}
    np.testing.assert_allclose(grouped["jackknife90_high"] / grouped["roughness_rel_R3"], 1.5)
    old = _table(PLAIN_METHOD, PLAIN_METHOD)  # a file without the jackknife+: no pi90 column at all
    assert _intervals(old) == {"jackknife90_low", "jackknife90_high", "surface_jackknife90_low",
                               "surface_jackknife90_high"}
    for table in (alone, grouped, old):  # every column is documented, the interval's with its method
        documented = {c.replace("<reference>", "R3") for c in PREDICTION_COLUMNS}
        assert set(table.columns) <= documented, set(table.columns) - documented
    assert "jackknife+" in PREDICTION_COLUMNS["pi90_low"] and "no coverage guarantee" in \
        PREDICTION_COLUMNS["jackknife90_low"]


def test_the_readme_describes_the_columns_as_the_table_names_them():
    from pathlib import Path

    readme = " ".join((Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8").split())
    assert "`pi90_low`, `pi90_high` are always the jackknife+ over the training specimens, with its coverage " \
           "guarantee" in readme
    assert "the plain jackknife, which has none (a press read with its surface's others, or a file without the " \
           "jackknife+), is `jackknife90_low`, `jackknife90_high` instead" in readme
