"""The groove model's file section (model/groove/file.py) through model/modelfile.py: written, loaded back as the
fitted law (the same predictions and reasons, bit for bit), and refused in one line where edited into nonsense."""
from __future__ import annotations

import copy
import json

import numpy as np
import pytest

import roughsense as rs
from roughsense.errors import ModelFileError
from roughsense.model import modelfile
from roughsense.model.groove.file import KIND
from roughsense.model.groove.law import GrooveInputError, GrooveLaw
from tests.model.groove.test_family import FORCES, grating_study


def _fitted():
    X, y, specimens, settings = grating_study()
    law = GrooveLaw().fit(X, y, contact=settings.contact, contact_names=settings.contact_names, specimens=specimens)
    return law, X, settings.contact


def _features() -> dict:
    return {"spectrum": rs.SpatialSpectrum().feature_definition(), "conditions": list(FORCES)}


def test_a_groove_model_file_loads_back_as_the_fitted_law(tmp_path):
    law, X, contact = _fitted()
    path = modelfile.save_model(tmp_path / "groove.json", law, feature_definition=_features(),
                                training={"study": "gratings"})
    section = json.loads(path.read_text())["model"]
    assert section["kind"] == KIND and section["terms"][0] == "log_groove_mm"
    assert section["contact_names"] == list(law.contact_names_)
    loaded = rs.load_model(path)
    assert isinstance(loaded, GrooveLaw) and loaded.family == "groove" and loaded.conditions == list(FORCES)
    np.testing.assert_array_equal(loaded.predict(X, contact=contact), law.predict(X, contact=contact))
    assert loaded.applicability(X, contact=contact) == law.applicability(X, contact=contact)
    assert loaded.applicability(X, contact=contact)[5] == "groove width unreadable in this press"
    wide = contact.copy()
    wide[0, 1::2] = 9.0  # a 9 mm groove: far outside the trained widths
    assert loaded.extrapolates(X[:1], contact=wide[:1]).all()
    assert "groove width 9.00 mm outside the trained" in loaded.applicability(X[:1], contact=wide[:1])[0]


def test_predicting_without_the_models_contact_measures_is_refused_in_one_line(tmp_path):
    law, X, contact = _fitted()
    path = modelfile.save_model(tmp_path / "groove.json", law, feature_definition=_features(), training={})
    loaded = rs.load_model(path)
    with pytest.raises(GrooveInputError, match="reads contact measures .*none were given"):
        loaded.predict(X)
    with pytest.raises(GrooveInputError, match=r"reads 6 contact measure\(s\) per row"):
        loaded.predict(X, contact=contact[:, :4])
    with pytest.raises(GrooveInputError, match="must be numbers"):
        loaded.predict(X[:1], contact=[["wide"] * 6])
    odd = np.array([[np.inf, -1.0, 0.0, np.nan, np.nan, 0.0]])  # no force gives a width: the terms put at their means
    assert np.isfinite(loaded.predict(X[:1], contact=odd)).all()
    assert loaded.applicability(X[:1], contact=odd)[0].startswith("groove width")
    with pytest.raises(ModelFileError, match="expects 135 features"):
        loaded.predict(X[:, :10], contact=contact)


def _edited(tmp_path, edit) -> ModelFileError:
    law, _, _ = _fitted()
    document = modelfile.model_document(law, feature_definition=_features(), training={})
    document = copy.deepcopy(document)
    edit(document["model"])
    document["sha256"] = modelfile._digest(document)  # the checksum is unkeyed: anyone can re-sign an edit
    with pytest.raises(ModelFileError) as caught:
        modelfile.model_from_document(document, path=tmp_path / "edited.json")
    return caught.value


@pytest.mark.parametrize(("edit", "message"), [
    (lambda m: m["coefficients"].__setitem__(0, 900.0), "a prediction must stay within 1e-6 to 1e6"),
    (lambda m: m.update(terms=["log_land_mm", "log_groove_mm"], coefficients=[0.1, 0.7], term_mean=[0.0, 0.0],
                        term_min=[-1.0, -1.0], term_max=[1.0, 1.0]), "in that order"),
    (lambda m: m.update(terms=["no_such_term"]), "model.terms must be some of"),
    (lambda m: m.__setitem__("contact_names", [n.replace("3N", "4N") for n in m["contact_names"]]),
     "feature definition's conditions"),
    (lambda m: m["domain"]["low"].__setitem__(0, 50.0), "empty training range"),
    (lambda m: m.pop("domain"), "lacks the field(s) model.domain"),
    (lambda m: m.__setitem__("extra", 1), "unknown field(s) model.extra"),
])
def test_an_edited_section_is_refused_naming_the_field(tmp_path, edit, message):
    error = _edited(tmp_path, edit)
    assert message in error.message and "\n" not in str(error)


def test_a_law_with_no_readable_press_is_refused():
    X, y, specimens, settings = grating_study()
    with pytest.raises(GrooveInputError, match="no press has readable land and groove widths"):
        GrooveLaw().fit(X, y, contact=np.full_like(settings.contact, np.nan), contact_names=settings.contact_names,
                        specimens=specimens)


def test_every_familys_training_fields_agree_where_they_share_a_name():
    """The training record's schema merges every family's fields by name (model/training_file.py): a field two
    families name must mean the same, or the later family's would refuse the earlier's files."""
    from roughsense.model.registry import engines

    for schema in ("training_schema", "fold_schema"):  # the jackknife+ folds' fields are merged the same way
        seen: dict = {}
        for family in engines():
            for name, node in getattr(family, schema).items():
                assert seen.setdefault(name, node) == node, f"{family.name} redefines {schema} field {name}"


def test_a_groove_models_training_record_is_checked_by_the_merged_schema(tmp_path):
    from roughsense.model.family import TrainingSet
    from roughsense.model.folds import fold_ids, training_mean_predictions
    from roughsense.model.groove.family import GrooveFamily

    X, y, specimens, settings = grating_study()
    folds, scheme = fold_ids(y.size, None, specimens, None)
    trained = GrooveFamily().train(TrainingSet(X, y, specimens, "loso", 0, folds, scheme,
                                               training_mean_predictions(y, folds), settings, {}, "tiny"))
    path = modelfile.save_model(tmp_path / "groove.json", trained.model, feature_definition=_features(),
                                training=trained.record)
    assert rs.load_model(path).training["terms_kept"]["log_groove_mm"] == 1.0


def test_a_training_record_stating_terms_the_model_does_not_offer_is_refused(tmp_path):
    law, _, _ = _fitted()
    with pytest.raises(ModelFileError, match="training.terms_kept: must state each offered term"):
        modelfile.save_model(tmp_path / "groove.json", law, feature_definition=_features(),
                             training={"terms_kept": {"log_groove_mm": 1.0}})
