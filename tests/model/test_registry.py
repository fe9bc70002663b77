"""A model family's whole life through the registry: a toy family, written and registered here with no edit to
src/, goes through ``analyse_study``, ``fit`` (``train_model`` and the command), its model file (written, checked and
loaded back), ``rs.predict`` and the ``predict`` command.

The toy is the null model itself: each held-out trial predicted by its training fold's mean, and the model file's
model the mean of every rating it was trained on. Its truths are independent of the code under test: its CV RMSE is
PLS's 0-component CV RMSE under the same folds (computed by PLS's own CV engine), in a balanced design no shuffling
of the specimens' targets changes it (its permutation p is exactly 1), and every prediction is the training mean.
"""
from __future__ import annotations

import json
import subprocess
import sys
from typing import ClassVar

import numpy as np
import pandas as pd
import pytest

import roughsense as rs
from roughsense.analysis.study_analysis import analyse_study
from roughsense.errors import ConfigError, ModelFileError, RoughsenseWarning
from roughsense.model import registry
from roughsense.model.family import FamilyEngine, FoldResult, Trained
from roughsense.model.loaded import FromModelFile, ModelFileInfo
from tests.analysis.test_dataset import make_study
from tests.analysis.test_study_analysis import synthetic_study

TOY = "training-mean"
TOY_KIND = "training-mean-v1"


def _fold_means(y: np.ndarray, folds: np.ndarray) -> np.ndarray:
    """Each row's prediction: the mean of y over every row of another fold (a plain loop, no shared code)."""
    out = np.empty(len(y))
    for label in np.unique(folds):
        held = folds == label
        out[held] = y[~held].mean()
    return out


def _folds(y, specimens, cv) -> np.ndarray:
    if cv == "loo":
        return np.arange(len(y))
    if cv == "loso":
        return np.asarray(specimens)
    return np.arange(len(y)) % int(cv)  # K folds, dealt in turn (the toy needs no shuffle)


class TrainingMean(FromModelFile):
    """The toy's estimator: it reads no spectrum and predicts the mean rating it was fitted on."""

    family: ClassVar[str] = TOY

    def fit(self, X, y) -> TrainingMean:
        self.n_features_in_, self.mean_ = int(np.shape(X)[1]), float(np.mean(y))
        return self

    def predict(self, X, surfaces=None) -> np.ndarray:
        return np.full(len(self._file_inputs(X)), self.mean_)

    def applicability(self, X, surfaces=None) -> list[str]:
        return [""] * len(X)  # no domain: it never claims to read a spectrum


class ToyCV:
    """The toy's CV as ``fit`` reports it."""

    def __init__(self, rmse: float, scheme: str):
        self.rmse, self.scheme = rmse, scheme


class ToyEngine(FamilyEngine):
    """The toy family's whole life, registered by dotted path."""

    name: ClassVar[str] = TOY
    kind: ClassVar[str] = TOY_KIND
    section_schema: ClassVar[dict] = {
        "type": "object", "required": ["kind", "n_features", "mean"], "additionalProperties": False,
        "properties": {"kind": {"const": TOY_KIND}, "n_features": {"type": "integer", "minimum": 1},
                       "mean": {"type": "number", "exclusiveMinimum": 0}}}
    training_schema: ClassVar[dict] = {"toy_cv_rmse": {"type": "number", "minimum": 0}}

    def cross_validate(self, X, y, specimens, cv, settings, max_components) -> FoldResult:
        out_of_fold = _fold_means(np.asarray(y, float), _folds(y, specimens, cv))
        rmse = float(np.sqrt(np.mean((out_of_fold - y) ** 2)))
        return FoldResult(out_of_fold, np.array([rmse, rmse]))

    def permuted_rmse(self, X, Y, specimens, cv, settings, max_components) -> np.ndarray:
        folds = _folds(Y[:, 0], specimens, cv)
        return np.array([np.sqrt(np.mean((_fold_means(column, folds) - column) ** 2)) for column in Y.T])

    def held_out_flags(self, X, y, specimens, settings, fold) -> np.ndarray:
        return np.zeros(len(y), dtype=bool)

    def train(self, data) -> Trained:
        fold = self.cross_validate(data.X, data.y, data.specimens, data.scheme, data.settings, 1)
        cv = ToyCV(float(fold.curve[1]), f"toy {data.scheme}")
        return Trained(TrainingMean().fit(data.X, data.y), cv, 1, {"toy_cv_rmse": cv.rmse})

    def fit_report(self, trained):
        return (pd.DataFrame({"model": [TOY], "rmse": [trained.cv.rmse]}),
                [f"toy: every surface is {trained.model.mean_:.4f}"])

    def section(self, model) -> dict:
        return {"kind": TOY_KIND, "n_features": model.n_features_in_, "mean": model.mean_}

    def check_fields(self, section, path) -> int:
        if not isinstance(section.get("n_features"), int):
            raise ModelFileError("model.n_features must be a whole number", path=path)
        return section["n_features"]

    def load(self, section, features, *, training, roughsense_version, path):
        model = TrainingMean()
        model.n_features_in_, model.mean_ = section["n_features"], float(section["mean"])
        model.model_file_ = ModelFileInfo(path, features, training, roughsense_version)
        return model


def _register() -> registry.Family:
    family = registry.Family(TOY, "training mean", "^", "#777777", paper=False, engine_path=f"{__name__}:ToyEngine")
    registry.register(family)
    return family


def test_the_registry_lists_the_families_and_their_engines_in_one_order():
    assert registry.MODEL_FAMILIES == registry.names() == ("pls", "peak-law", "groove")
    assert tuple(e.name for e in registry.engines()) == registry.names()
    assert [f.name for f in registry.registry() if f.paper] == [registry.paper_family().name] == ["pls"]
    assert registry.default_model() == registry.DEFAULT_MODEL == "peak-law"  # one land/groove geometry (the paper)
    assert registry.default_model(varies_geometry=True) == registry.GEOMETRY_MODEL == "groove"
    assert all(registry.engine(name).name == name for name in registry.names())
    assert registry.check_model_name(" Peak-Law ") == "peak-law"
    with pytest.raises(ConfigError, match="--model must be one of pls, peak-law, groove, got 'ridge'"):
        registry.check_model_name("ridge")
    kinds = registry.kinds()  # each family's model-file kind, one each, found back by the registry
    assert len(set(kinds)) == 3 and all(registry.engine_of_kind(k).kind == k for k in kinds)
    assert registry.engine_of_kind("no-such-kind") is None


def test_a_family_registered_is_listed_after_the_others_and_removed_cleanly(toy):
    assert registry.names() == ("pls", "peak-law", "groove", TOY)
    assert registry.check_model_name("Training-Mean") == TOY and registry.family(TOY) is toy
    assert isinstance(registry.engine(TOY), ToyEngine) and registry.engine_of_kind(TOY_KIND).name == TOY
    with pytest.raises(ConfigError, match="already registered"):
        registry.register(toy)
    with pytest.raises(ConfigError, match=f"one of pls, peak-law, groove, {TOY}"):
        registry.check_model_name("ridge")
    registry.unregister(TOY)
    assert registry.names() == ("pls", "peak-law", "groove")


def test_the_registry_is_light_and_the_fingerprint_follows_its_engines():
    """The names load no NumPy (``--help`` reads them); the engines, imported by dotted path when first asked for,
    are still part of the code a cached result is keyed on."""
    code = "import sys, roughsense.model.registry; print('numpy' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split() == [
        "False"]
    from roughsense._util.fingerprint import module_closure

    closure = set(module_closure("roughsense.analysis.family_fits"))
    assert {"roughsense.model.registry", "roughsense.model.pls.family", "roughsense.model.peak_law.family"} <= closure


@pytest.fixture
def toy():
    """The toy family registered after the built-in ones for one test, and removed after it."""
    family = _register()
    try:
        yield family
    finally:
        registry.unregister(TOY)


@pytest.fixture(scope="module")
def toy_analysis():
    """The study analysed with the toy family beside the others, once for the module (frozen: tests only read it);
    the registry is patched while it is analysed, and again in each test that reads it (``with_toy``)."""
    _register()
    try:
        study, features = synthetic_study(repetitions=2, pads=("smooth",))
        return analyse_study(study, features=features, max_components=2, conditions=("1N", "combined"),
                             n_permutations=9, models=("pls", "peak-law", TOY))
    finally:
        registry.unregister(TOY)


@pytest.fixture
def with_toy(toy, toy_analysis):
    return toy_analysis


def test_a_third_family_runs_through_the_study_beside_the_others(with_toy):
    analysis = with_toy
    assert analysis.models == ("pls", "peak-law", TOY)
    for table in (analysis.results("loo"), analysis.results("loso"), analysis.predictions(), analysis.cv_table(),
                  analysis.controls):
        assert list(dict.fromkeys(table["model"])) == ["pls", "peak-law", TOY]  # the registry's order
    pls_null = analysis.cv_table().query("model == 'pls' and n_components == 0").set_index(["condition", "cv"])
    controls = analysis.controls.set_index(["condition", "cv", "model"])
    for condition in ("1N", "combined"):
        for cv in ("loo", "loso"):
            toy = controls.loc[(condition, cv, TOY)]
            # The toy's pooled CV RMSE is the null model's, computed by PLS's CV engine at 0 components.
            assert toy["rmse"] == pytest.approx(pls_null.loc[(condition, cv), "rmse"], rel=1e-12)
            assert toy["null_rmse"] == pytest.approx(controls.loc[(condition, cv, "pls"), "null_rmse"], rel=1e-12)
            assert not toy["beats_null"] and not toy["passes"]
            assert toy["permutation_p"] == 1.0  # balanced: no shuffling changes the training mean's RMSE


def test_a_third_familys_predictions_are_its_training_fold_means(with_toy):
    analysis = with_toy
    predictions = analysis.predictions()
    for (condition, cv), rows in predictions[predictions["model"] == TOY].groupby(["condition", "cv"]):
        pls = predictions[predictions["model"].eq("pls") & predictions["condition"].eq(condition)
                          & predictions["cv"].eq(cv)]
        assert list(rows["image"]) == list(pls["image"])  # the same trials, in the same order
        target = rows["specimen"].map(analysis.perceived.set_index("specimen")["gmean"]).to_numpy(float)
        expected = [target[np.arange(len(target)) != i].mean() if cv == "loo" else
                    target[rows["specimen"].to_numpy() != s].mean()
                    for i, s in enumerate(rows["specimen"].to_numpy())]
        np.testing.assert_allclose(rows["prediction"], expected, rtol=1e-12)
    loso = analysis.held_out.query(f"model == '{TOY}'")
    assert list(loso["scheme"]) == ["specimen"] * 2  # stricter schemes: the toy has none; the study's LOSO is shown
    assert (loso["flagged_share"] == 0).all()
    assert TOY not in set(analysis.presses.get("model", pd.Series(dtype=str)))  # it reads no surface


def test_claims_stay_the_paper_familys_with_a_third_family_beside_it(with_toy):
    study, features = synthetic_study(repetitions=2, pads=("smooth",))
    alone = analyse_study(study, features=features, max_components=2, conditions=("1N", "combined"),
                          n_permutations=9, models=("pls",))
    pd.testing.assert_frame_equal(with_toy.claims, alone.claims)


def test_fold_settings_pass_the_same_keywords_as_the_dict_they_replace():
    from roughsense.analysis.family_fits import law_settings
    from roughsense.model.family import FoldSettings

    X = np.ones((4, 6))
    law = law_settings(X, np.linspace(0.1, 1.0, 3), 1.0, ["a", "a", "b", "b"])
    assert list(law) == ["freq_per_mm", "n_blocks", "pad_ridge_period_mm", "surfaces"] and law["n_blocks"] == 2
    again = FoldSettings.of(law).law()
    assert list(again) == list(law) and all(again[k] is law[k] for k in law)  # the very arrays, in the same order
    partial = FoldSettings.of({"freq_per_mm": law["freq_per_mm"]})
    assert (partial.n_blocks, partial.pad_ridge_period_mm, partial.surfaces) == (1, None, None)  # the kernels' defaults
    assert FoldSettings.of(None) is None and FoldSettings.of(partial) is partial


def test_the_fit_record_is_frozen(with_toy):
    import dataclasses


    pls = with_toy.condition_fit("smooth", "combined", "loso", "pls")
    assert pls.best == int(np.argmin(pls.curve))
    assert len(pls.per_specimen) == 14
    assert pls.held_out_flags is not None and pls.interval_check is None  # PLS: flags, no leave-two-out check
    law = with_toy.condition_fit("smooth", "combined", "loso", "peak-law")
    assert (law.best, law.one_se, law.per_specimen, law.curve.size) == (1, 1, {}, 2)
    assert law.interval_check is not None and len(law.interval_check) == 14
    with pytest.raises(dataclasses.FrozenInstanceError):
        pls.best = 3


# --------------------------------------------------------------------------- fit, the model file and predict


@pytest.fixture(scope="module")
def life_study(tmp_path_factory):
    """A tiny study with images (fingerprint pad, six specimens, three presses each) to fit and predict on."""
    return make_study(tmp_path_factory.mktemp("life") / "tiny", repetitions=3)


def _ratings_mean(study_dir, condition: str = "2N") -> float:
    """The mean target over the trials of one condition, from the study's own tables (the toy's whole model)."""
    from roughsense.analysis import dataset
    from roughsense.io.study import read_study

    study = read_study(study_dir)
    trials = study.manifest[study.manifest["pad"].eq("fingerprint") & study.manifest["condition"].eq(condition)]
    perceived = dataset.perceived_roughness(study).set_index("specimen")["gmean"]
    return float(trials["specimen"].map(perceived).mean())


def test_a_registered_family_is_trained_saved_loaded_and_predicts_through_the_api(toy, life_study, tmp_path):
    from roughsense.analysis.training import train_model
    from roughsense.io.study import read_study
    from roughsense.model.modelfile import load_model, save_model

    trained = train_model(read_study(life_study), pad="fingerprint", condition="2N", model=TOY, cv="loso")
    mean = _ratings_mean(life_study)
    assert isinstance(trained.model, TrainingMean) and trained.family == TOY
    assert trained.model.mean_ == pytest.approx(mean, rel=1e-12)
    assert trained.training["toy_cv_rmse"] == trained.cv.rmse and trained.cv.scheme == "toy loso"
    assert trained.training["unseen"]["passes_controls"] is False  # the training mean never beats itself
    assert "interval" in trained.training and "jackknife_plus" not in trained.training  # it keeps no folds
    path = save_model(tmp_path / "toy.json", trained.model, feature_definition=trained.feature_definition,
                      training=trained.training)
    document = json.loads(path.read_text())
    assert document["model"] == {"kind": TOY_KIND, "n_features": trained.n_features, "mean": trained.model.mean_}
    loaded = load_model(path)
    assert isinstance(loaded, TrainingMean) and loaded.mean_ == trained.model.mean_ and loaded.path == path
    images = sorted(str(p) for p in (life_study / "images").glob("*2N*"))[:4]
    with pytest.warns(RoughsenseWarning):  # it fails its controls, and says so
        table = rs.predict(path, images)
    [column] = [c for c in table.columns if c.startswith("roughness_rel_")]
    assert list(table["model"]) == [TOY] * 4
    np.testing.assert_allclose(table.loc[~table["withheld"], column], mean, rtol=5e-3)  # the CSV's 3 digits


def test_a_model_file_of_a_family_not_registered_is_refused_naming_its_kind(toy, life_study, tmp_path):
    from roughsense.analysis.training import train_model
    from roughsense.io.study import read_study
    from roughsense.model.modelfile import load_model, save_model

    trained = train_model(read_study(life_study), pad="fingerprint", condition="2N", model=TOY)
    path = save_model(tmp_path / "toy.json", trained.model, feature_definition=trained.feature_definition,
                      training=trained.training)
    registry.unregister(TOY)
    with pytest.raises(ModelFileError, match=f"model kind '{TOY_KIND}' is not supported"):
        load_model(path)


def test_the_fit_and_predict_commands_run_a_registered_family(toy, life_study, tmp_path, run_cli):
    out = tmp_path / "toy.json"
    code, stdout, err = run_cli("fit", "--study", life_study, "--pad", "fingerprint", "--condition", "2N", "--model",
                                TOY, "--cv", "3", "--out", out)
    assert code == 0, err
    mean = _ratings_mean(life_study)
    assert "toy 3 CV, model training-mean" in stdout and f"toy: every surface is {mean:.4f}" in stdout
    assert json.loads(out.read_text())["model"]["kind"] == TOY_KIND
    pred = tmp_path / "toy.csv"
    code, _, err = run_cli("predict", out, "--study", life_study, "--out", pred)
    assert code in (0, 3), err  # 3: the contact-image gate withheld a press (said on stderr)
    table = pd.read_csv(pred)
    [column] = [c for c in table.columns if c.startswith("roughness_rel_")]
    assert set(table["model"]) == {TOY}
    np.testing.assert_allclose(table[column].dropna(), mean, rtol=5e-3)


def test_an_option_the_family_does_not_declare_is_refused_naming_one_that_does(toy, life_study, tmp_path, run_cli):
    code, _, err = run_cli("fit", "--study", life_study, "--pad", "fingerprint", "--condition", "2N", "--model", TOY,
                           "--rule", "1se", "--out", tmp_path / "toy.json")
    assert code == 2 and "--rule chooses PLS components; the training mean takes no --rule" in err
    assert "use --model pls" in err and not (tmp_path / "toy.json").exists()


def test_fit_model_help_is_the_registrys_description_and_names_no_peak_height_term(run_cli):
    """Issue 46: fit --model's help said the peak law reads "where the spectrum peaks and how high", but the law's
    terms are the peak's frequency and the contact's shape (docs/peak_law.md: the peak amplitude earned no term).
    The help is each registered family's description (one home), and no description gives the law a height term."""
    import re

    from roughsense.model.peak_law.law import PeakPowerLaw

    law = PeakPowerLaw().fit(*_peaked_gratings())
    assert law.coef_[1] == 0.0  # the peak amplitude is no term of today's law
    help_text = registry.model_help()
    for family in registry.registry():
        assert family.description and f"{family.name}" in help_text and family.description in help_text
    described = registry.family(registry.PEAK_LAW).description
    assert "how high" not in help_text and "height is no term" in described and "shape" in described
    code, out, _ = run_cli("fit", "--help")
    text = re.sub(r"[\s│]+", " ", out)  # rich wraps help text inside a box
    # each built-in family's description, as the registry gives it (the help is built when fit's module is first
    # imported, so a family a test registers for a while may or may not be listed beside them)
    assert code == 0 and "how high" not in text
    for family in registry.registry():
        if family.name in registry.MODEL_FAMILIES:
            assert re.sub(r"\s+", " ", family.description) in text, family.name


def _peaked_gratings():
    """Spectra peaking at 1 / period for gratings of 2-5 mm, two presses each, rated as a power law of the period."""
    f = rs.frequency_grid()
    periods = np.repeat([2.0, 3.0, 4.0, 5.0], 2)
    heights = np.tile([1.0, 3.0], 4)  # a peak height that varies and says nothing of the rating
    return heights[:, None] * np.exp(-((f - 1 / periods[:, None]) / 0.05) ** 2) + 0.01, (periods / 3) ** 0.9
