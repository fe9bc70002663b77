"""``roughsense fit`` and ``roughsense predict`` end to end on a tiny synthetic study, and their bad inputs."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

import roughsense
from roughsense import SIMPLS, pls_cv
from roughsense._util.text import counted
from roughsense.analysis import dataset
from roughsense.errors import InputError
from roughsense.io.study import read_study
from tests.analysis.test_dataset import SPECIMENS, make_study
from tests.model.test_gate_file import ungated


@pytest.fixture(scope="module")
def study_dir(tmp_path_factory):
    return make_study(tmp_path_factory.mktemp("cli") / "tiny", repetitions=3)


@pytest.fixture(scope="module")
def data(study_dir):
    study = read_study(study_dir)
    features = dataset.study_features(study)
    perceived = dataset.perceived_roughness(study)

    def matrix(condition):
        X, meta = dataset.condition_matrix(features, "fingerprint", condition)
        return X, dataset.targets(meta, perceived), meta

    return matrix


#: The predict CSV rounds roughness to 3 significant digits.
RTOL_3_DIGITS = 5e-3


def roughness(table):
    """The predict CSV's roughness column (named for the reference it is a ratio to)."""
    [name] = [c for c in table.columns if c.startswith("roughness_rel_")]
    return table[name]


def fit(run_cli, study_dir, out, *extra):
    """``roughsense fit`` of the paper's PLS unless ``extra`` names a --model (the CLI's default is the peak law)."""
    model = () if "--model" in extra else ("--model", "pls")
    return run_cli("fit", "--study", study_dir, "--pad", "fingerprint", "--out", out, *model, *extra)


def test_fit_chooses_the_cv_minimum_and_stores_the_curve(run_cli, study_dir, data, tmp_path):
    out = tmp_path / "m.json"
    code, stdout, err = fit(run_cli, study_dir, out, "--condition", "2N", "--max-components", "6")
    assert code == 0, err
    X, y, _ = data("2N")
    expected = pls_cv(X, y, max_components=6, cv="loo")
    k = expected.best_n_components
    assert f"chosen: {counted(k, 'component')} (" in stdout
    for rmse in expected.rmse:  # the curve is printed
        assert f"{rmse:.5f}" in stdout
    document = json.loads(out.read_text())
    assert document["training"]["cv_rmse"] == pytest.approx(expected.rmse.tolist(), rel=1e-12)
    assert document["training"]["n_components"] == k == document["model"]["n_components"]
    assert document["training"]["pad"] == "fingerprint" and document["training"]["condition"] == "2N"
    assert document["features"]["conditions"] == ["2N"]
    assert document["features"]["spectrum"]["px_per_mm"] == 20.0 and document["features"]["spectrum"]["roi"] == [0, 16, 600, 32]

    # predict reproduces an independent refit of SIMPLS on the same data, image by image
    _, _, meta = data("2N")
    images = [study_dir / name for name in meta["image"]]
    pred = tmp_path / "pred.csv"
    code, stdout, err = run_cli("predict", out, *images, "--out", pred)
    assert code == 0, err
    table = pd.read_csv(pred)
    assert list(table.columns) == ["image", "pad", "condition", "model", "passes_controls", "px_per_mm",
                                   "roughness_rel_R3", "jackknife90_low", "jackknife90_high", "orientation_deg",
                                   "read_as", "contact_p", "withheld", "extrapolates", "outside"] and len(table) == len(images)
    assert set(table["px_per_mm"]) == {20.0}  # the model's own scale, said as --study and --px-per-mm say theirs
    assert pred.read_text().splitlines()[1].split(",")[5] == "20.0"
    assert set(table["model"]) == {"pls"}
    assert table["extrapolates"].dtype == bool and not table["extrapolates"].any()  # training spectra, in its domain
    assert "all 18 predictions within what the model was trained on" in stdout
    assert set(table["pad"]) == {"fingerprint"} and set(table["condition"]) == {"2N"}
    np.testing.assert_allclose(roughness(table), SIMPLS(k).fit(X, y).predict(X), rtol=RTOL_3_DIGITS)

    code, stdout, err = run_cli("predict", out, images[0], images[5])
    assert code == 0, err
    assert "roughness" in stdout and images[5].name in stdout
    assert f"{roughness(table)[5]:.3g}" in stdout
    # Long image paths in an 80-column terminal: one line per image, ending with its file's name (the table broke
    # into blocks joined by a backslash)
    lines = stdout.splitlines()
    assert max(map(len, lines)) <= 80 and not any(line.endswith("\\") for line in lines), stdout
    row = next(line for line in lines if images[5].name in line)
    assert f"{roughness(table)[5]:.3g}" in row.split()


def test_combined_model_takes_trials_of_three(run_cli, study_dir, data, tmp_path):
    out = tmp_path / "combined.json"
    code, stdout, err = fit(run_cli, study_dir, out, "--condition", "combined", "--max-components", "5", "--cv", "loso")
    assert code == 0, err
    X, y, meta = data("combined")
    assert X.shape == (18, 135)
    expected = pls_cv(X, y, max_components=5, groups=meta["specimen"].to_numpy())
    assert f"chosen: {counted(expected.best_n_components, 'component')} (" in stdout
    assert "leave-one-group-out" in stdout
    trials = [[study_dir / meta[f"image_{f}"][i] for f in ("1N", "2N", "3N")] for i in (0, 7)]
    pred = tmp_path / "p.csv"
    flags = [arg for slot, force in enumerate(("1n", "2n", "3n")) for arg in (f"--images-{force}", *(t[slot] for t in trials))]
    code, _, err = run_cli("predict", out, *flags, "--out", pred)
    assert code == 0, err
    table = pd.read_csv(pred)
    assert list(table.columns) == ["image_1N", "image_2N", "image_3N", "pad", "condition", "model", "passes_controls",
                                   "px_per_mm", "roughness_rel_R3", "jackknife90_low", "jackknife90_high",
                                   "orientation_deg", "read_as", "contact_p", "withheld", "extrapolates",
                                   "outside"] and len(table) == 2
    assert [table[f"image_{f}N"][i] for i in range(2) for f in (1, 2, 3)] == [str(p) for t in trials for p in t]
    assert set(table["pad"]) == {"fingerprint"} and set(table["condition"]) == {"combined"}
    refit = SIMPLS(expected.best_n_components).fit(X, y).predict(X[[0, 7]])
    np.testing.assert_allclose(roughness(table), refit, rtol=RTOL_3_DIGITS)

    # the flags in another order, and --images-2n=FILE, give the same trials
    reordered = ["--images-3n", *(t[2] for t in trials), f"--images-2n={trials[0][1]}", trials[1][1],
                 "--images-1n", *(t[0] for t in trials)]
    code, stdout, err = run_cli("predict", out, *reordered)
    assert code == 0, err
    assert f"{roughness(table)[1]:.3g}" in stdout

    # from the manifest: every trial of the model's pad, grouped by (specimen, repetition) and force
    by_study = tmp_path / "s.csv"
    code, _, err = run_cli("predict", out, "--study", study_dir, "--out", by_study)
    assert code == 0, err
    grouped = pd.read_csv(by_study)
    assert list(grouped.columns) == ["specimen", "repetition", "image_1N", "image_2N", "image_3N", "pad", "condition",
                                     "model", "passes_controls", "px_per_mm", "roughness_rel_R3", "jackknife90_low",
                                     "jackknife90_high", "surface_roughness_rel_R3", "surface_extrapolates",
                                     "orientation_deg", "read_as", "contact_p", "withheld", "extrapolates", "outside"]
    assert set(grouped["px_per_mm"]) == {20.0} and set(grouped["read_as"]) == {"surface"}  # the study's own scale
    assert len(grouped) == len(meta) == 18
    expected_rows = meta.sort_values(["specimen", "repetition"]).reset_index(drop=True)
    for f in ("1N", "2N", "3N"):
        assert list(grouped[f"image_{f}"]) == [str(study_dir / p) for p in expected_rows[f"image_{f}"]]
    order = meta.sort_values(["specimen", "repetition"]).index.to_numpy()
    np.testing.assert_allclose(roughness(grouped), SIMPLS(expected.best_n_components).fit(X, y).predict(X[order]),
                               rtol=RTOL_3_DIGITS)
    code, _, err = run_cli("predict", out, "--study", study_dir, "--specimen", "C2", "--specimen", "R4", "--out",
                           tmp_path / "two.csv")
    assert code == 0, err
    two = pd.read_csv(tmp_path / "two.csv")
    assert list(two["specimen"]) == ["C2"] * 3 + ["R4"] * 3 and list(two["repetition"]) == [1, 2, 3] * 2


def _one_line(code, err, *needles):
    assert code == 2, err
    assert err.startswith("roughsense: error:") and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    for needle in needles:
        assert needle in err, err


def test_combined_model_refuses_what_it_cannot_group(run_cli, study_dir, data, tmp_path):
    out = tmp_path / "combined.json"
    assert fit(run_cli, study_dir, out, "--condition", "combined", "--max-components", "2")[0] == 0
    _, _, meta = data("combined")
    one, two, three = (study_dir / meta[f"image_{f}"][0] for f in ("1N", "2N", "3N"))
    reps = [study_dir / meta["image_1N"][i] for i in range(3)]  # R?_1N_1.._3: the mis-grouping
    # bare images carry no force slot: refused, with the two ways to give them
    code, _, err = run_cli("predict", out, *reps)
    _one_line(code, err, "bare images", "--study DIR", "--images-1n ... --images-2n ... --images-3n ...")
    # a slot's force is spelled as every number is read: no digits of another script, no underscores
    for label in ("\u0661n", "1_0n"):
        code, _, err = run_cli("predict", out, f"--images-{label}", one, "--images-2n", two, "--images-3n", three)
        _one_line(code, err, f"--images-{label}: expected a force like --images-1n")
    # a file whose name says another force than its slot
    code, _, err = run_cli("predict", out, "--images-1n", one, "--images-2n", reps[1], "--images-3n", three)
    _one_line(code, err, f"{reps[1].name!r} fills the 2N slot but its name says 1N")
    # counts must match; every force of the model is needed; a force it does not use is refused
    code, _, err = run_cli("predict", out, "--images-1n", one, reps[1], "--images-2n", two, "--images-3n", three)
    _one_line(code, err, "2 at 1N, 1 at 2N, 1 at 3N")
    code, _, err = run_cli("predict", out, "--images-1n", one, "--images-2n", two)
    _one_line(code, err, "--images-3n is missing")
    code, _, err = run_cli("predict", out, "--images-1n", one, "--images-2n", two, "--images-3n", three,
                           "--images-4n", three)
    _one_line(code, err, "not 4N")
    code, _, err = run_cli("predict", out, "--images-1x", one)
    _one_line(code, err, "--images-1x")
    code, _, err = run_cli("predict", out, "--images-1n", one, "--images-2n", two, "--images-3n", three, "--bogus")
    _one_line(code, err, "no such option: --bogus")
    code, _, err = run_cli("predict", out, one, "--study", study_dir)
    _one_line(code, err, "one way")
    code, _, err = run_cli("predict", out, "--images-1n", one, "--specimen", "R3")
    _one_line(code, err, "--specimen", "--study")
    code, _, err = run_cli("predict", out, "--study", study_dir, "--specimen", "R9")
    _one_line(code, err, "specimen 'R9'")


def test_predict_from_a_manifest_refuses_a_row_that_contradicts_its_slot(run_cli, tmp_path):
    root = make_study(tmp_path / "s", repetitions=2)
    model = tmp_path / "m.json"
    assert fit(run_cli, root, model, "--condition", "combined", "--max-components", "2")[0] == 0
    manifest = pd.read_csv(root / "manifest.csv")
    i = manifest.index[manifest["image"].str.contains("R3_2N_1")][0]
    j = manifest.index[manifest["image"].str.contains("R3_1N_1")][0]
    manifest.loc[[i, j], "image"] = manifest.loc[[j, i], "image"].to_numpy()  # two files swapped in the manifest
    manifest.to_csv(root / "manifest.csv", index=False)
    code, _, err = run_cli("predict", model, "--study", root)
    _one_line(code, err, "manifest.csv", f"row {min(i, j) + 2}", "slot but its name says")
    # a trial missing a force is named, not scored with a neighbour's image
    manifest = manifest.drop(index=[i, j])
    manifest.to_csv(root / "manifest.csv", index=False)
    code, _, err = run_cli("predict", model, "--study", root)
    _one_line(code, err, "specimen 'R3', repetition 1", "no image at 1N")
    code, _, err = run_cli("predict", model, "--study", root, "--specimen", "C2")  # other specimens still score
    assert code == 0, err


def test_single_force_model_takes_images_or_a_study(run_cli, study_dir, data, tmp_path):
    model = tmp_path / "m.json"
    assert fit(run_cli, study_dir, model, "--condition", "1N", "--max-components", "3")[0] == 0
    X, y, meta = data("1N")
    k = json.loads(model.read_text())["model"]["n_components"]
    code, _, err = run_cli("predict", model, "--study", study_dir, "--specimen", "R2", "--out", tmp_path / "p.csv")
    assert code == 0, err
    table = pd.read_csv(tmp_path / "p.csv")
    rows = meta.index[meta["specimen"] == "R2"].to_numpy()
    assert list(table["image"]) == [str(study_dir / p) for p in meta["image"][rows]]
    assert list(table["repetition"]) == [1, 2, 3] and set(table["condition"]) == {"1N"}
    np.testing.assert_allclose(roughness(table), SIMPLS(k).fit(X, y).predict(X[rows]), rtol=RTOL_3_DIGITS)
    code, _, err = run_cli("predict", model, "--images-1n", study_dir / meta["image"][0])
    assert code == 0, err
    wrong = next((study_dir / "images").glob("*_2N_1.png"))
    code, _, err = run_cli("predict", model, wrong)  # a 1N model given a 2N image
    _one_line(code, err, f"{wrong.name!r} fills the 1N slot but its name says 2N")


def test_one_se_rule(run_cli, study_dir, data, tmp_path):
    out = tmp_path / "m.json"
    code, stdout, err = fit(run_cli, study_dir, out, "--condition", "3N", "--cv", "loso", "--rule", "1se",
                            "--max-components", "6")
    assert code == 0, err
    X, y, meta = data("3N")
    expected = pls_cv(X, y, max_components=6, groups=meta["specimen"].to_numpy())
    assert f"chosen: {counted(expected.one_se_n_components, 'component')} (" in stdout
    document = json.loads(out.read_text())
    assert document["model"]["n_components"] == expected.one_se_n_components
    assert document["training"]["rule"] == "1se" and document["training"]["cv"] == "loso"


def test_kfold_is_reproducible_from_the_seed(run_cli, study_dir, tmp_path):
    outputs = []
    for name, seed in (("a", "5"), ("b", "5")):
        out = tmp_path / f"{name}.json"
        code, _, err = fit(run_cli, study_dir, out, "--condition", "1N", "--cv", "3", "--seed", seed, "--max-components", "4")
        assert code == 0, err
        outputs.append(out.read_bytes())
    assert outputs[0] == outputs[1]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--condition", "4N"), "--condition must be one of"),
        (("--condition", "1N", "--cv", "bootstrap"), "--cv must be loo, loso"),
        (("--condition", "1N", "--max-components", "40"), "more than the data support"),
        (("--condition", "1N", "--rule", "best"), "--rule"),
    ],
)
def test_fit_bad_options(run_cli, study_dir, tmp_path, args, message):
    out = tmp_path / "m.json"
    code, _, err = fit(run_cli, study_dir, out, *args)
    assert code == 2 and message in err and "Traceback" not in err
    assert not out.exists()


def test_fit_bad_inputs(run_cli, study_dir, tmp_path):
    out = tmp_path / "m.json"
    code, _, err = run_cli("fit", "--study", tmp_path / "nowhere", "--pad", "x", "--condition", "1N", "--out", out)
    assert code == 2 and "nowhere" in err and "study folder not found" in err
    code, _, err = run_cli("fit", "--study", study_dir, "--pad", "glass", "--condition", "1N", "--out", out)
    assert code == 2 and "pad 'glass'" in err and "manifest.csv" in err and "fingerprint" in err
    assert not out.exists()
    out.write_text("mine")
    code, _, err = fit(run_cli, study_dir, out, "--condition", "1N", "--max-components", "2")
    assert code == 2 and "--force" in err and out.read_text() == "mine"


def test_fit_needs_ratings(run_cli, tmp_path):
    root = make_study(tmp_path / "s", repetitions=2)
    (root / "ratings.csv").unlink()
    code, _, err = fit(run_cli, root, tmp_path / "m.json", "--condition", "1N")
    assert code == 2 and "ratings.csv" in err


def test_fit_names_the_ratings_file_when_a_specimen_was_never_rated(run_cli, tmp_path):
    root = make_study(tmp_path / "s", repetitions=2)
    ratings = pd.read_csv(root / "ratings.csv")
    ratings[ratings.specimen != "C2"].to_csv(root / "ratings.csv", index=False)
    out = tmp_path / "m.json"
    code, _, err = fit(run_cli, root, out, "--condition", "1N")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert err.strip() == (f"roughsense: error: {root / 'ratings.csv'}: "
                           "no perceived roughness for specimen(s) C2 (not in the ratings)")
    assert not out.exists()


def test_predict_bad_inputs(run_cli, study_dir, tmp_path):
    model = tmp_path / "m.json"
    code, _, err = fit(run_cli, study_dir, model, "--condition", "1N", "--max-components", "3")
    assert code == 0, err
    image = next((study_dir / "images").glob("*_1N_1.png"))
    code, _, err = run_cli("predict", model, tmp_path / "missing.png")
    assert code == 2 and "missing.png" in err
    damaged = tmp_path / "damaged.json"
    damaged.write_text(model.read_text()[:-40])
    code, _, err = run_cli("predict", damaged, image)
    assert code == 2 and "damaged.json" in err and "truncated" in err
    pred = tmp_path / "p.csv"
    pred.write_text("keep")
    code, _, err = run_cli("predict", model, image, "--out", pred)
    assert code == 2 and "--force" in err and pred.read_text() == "keep"
    code, _, err = run_cli("predict", model, image, "--out", pred, "--force")
    assert code == 0 and len(pd.read_csv(pred)) == 1


def test_help_describes_both_commands(run_cli):
    code, out, _ = run_cli("--help")
    assert code == 0 and "fit" in out and "predict" in out
    code, out, _ = run_cli("fit", "--help")
    assert code == 0 and "--max-components" in out and "loso" in out
    code, out, _ = run_cli("predict", "--help")
    text = re.sub(r"[\s│]+", " ", out)  # rich wraps help text inside a box
    assert code == 0 and "--images-1n" in text and "--study" in text and "i-th image of each flag form one trial" in text


@given(force_n=st.decimals(min_value="0.1", max_value="50", places=2).map(float),
       style=st.sampled_from(["{pad}_{spec}_{f}N_r01.png", "{spec}_{pad}_r01_{f}N.png", "{spec}-{f}n-{pad}.tif"]),
       spec=st.sampled_from(["R3", "C2.5", "sin_3_0.5", "rand_1.5_0.2"]))
def test_the_force_a_file_name_states(force_n, style, spec):
    from roughsense.model.trials import check_slot, forces_in_name

    name = style.format(pad="fingerprint", spec=spec, f=f"{force_n:g}")
    assert forces_in_name(f"images/{name}") == {force_n}
    check_slot(name, f"{force_n:g}N")  # its own slot: accepted
    with pytest.raises(InputError, match="slot but its name says"):
        check_slot(name, f"{force_n + 1:g}N")
    assert forces_in_name(name.replace(f"{force_n:g}", "x")) == set()  # no force stated: nothing to contradict


# --------------------------------------------------------------------------- the peak law


def grid_per_mm():
    from roughsense.sensor.spectrum import SpatialSpectrum

    return np.asarray(SpatialSpectrum(px_per_mm=20.0, roi=(0, 16, 600, 32)).fit().freq_per_mm_)


def null_predictions(y, folds):
    """The training mean of every fold, by brute force (the independent truth for the file's null RMSE)."""
    return np.array([y[folds != folds[i]].mean() for i in range(len(y))])


@pytest.mark.parametrize(("condition", "cv"), [("combined", "loso"), ("2N", "loo")])
def test_fit_peak_law_writes_the_law_fitted_in_python(run_cli, study_dir, data, tmp_path, condition, cv):
    from roughsense.model.modelfile import load_model
    from roughsense.model.peak_law.cv import peak_law_cv
    from roughsense.model.peak_law.law import PeakPowerLaw

    out = tmp_path / "law.json"
    code, stdout, err = fit(run_cli, study_dir, out, "--condition", condition, "--cv", cv, "--model", "Peak-Law")
    assert code == 0, err
    X, y, meta = data(condition)
    blocks = 3 if condition == "combined" else 1
    law = PeakPowerLaw(freq_per_mm=grid_per_mm(), n_blocks=blocks).fit(X, y, surfaces=meta["specimen"])  # no ridges
    document = json.loads(out.read_text())
    assert document["model"]["kind"] == "peak-power-law" and document["model"]["pad_ridge_period_mm"] is None
    assert document["model"]["n_blocks"] == blocks and document["model"]["coefficients"] == law.coef_.tolist()
    loaded = load_model(out)
    surfaces = meta["specimen"].to_numpy()
    np.testing.assert_allclose(loaded.predict(X, surfaces), law.predict(X, surfaces), rtol=1e-12, atol=0)
    assert not loaded.extrapolates(X, surfaces).any()  # every training trial lies in the law's domain

    groups = surfaces if cv == "loso" else None
    held_out = peak_law_cv(X, y, groups=groups, freq_per_mm=grid_per_mm(), n_blocks=blocks, surfaces=surfaces)[0]
    law_rmse = np.sqrt(np.mean((held_out - y) ** 2))
    folds = groups if groups is not None else np.arange(len(y))
    null_rmse = np.sqrt(np.mean((null_predictions(y, folds) - y) ** 2))
    training = document["training"]
    assert training["model"] == "peak-law" and training["cv_models"] == ["training mean", "peak-law"]
    assert training["cv_rmse"] == pytest.approx([null_rmse, law_rmse], rel=1e-12)
    assert training["cv"] == cv and training["condition"] == condition
    assert f"CV RMSE {law_rmse:.5f} (training mean {null_rmse:.5f})" in stdout
    assert law_rmse < null_rmse  # the ratings are a power law of the period: the law must beat the mean

    # predict --study scores every trial as the law fitted in Python does, none of them extrapolating
    pred = tmp_path / "p.csv"
    code, stdout, err = run_cli("predict", out, "--study", study_dir, "--out", pred)
    assert code == 0, err
    table = pd.read_csv(pred)
    order = meta.sort_values(["specimen", "repetition"]).index.to_numpy()
    np.testing.assert_allclose(roughness(table), law.predict(X[order]), rtol=RTOL_3_DIGITS)
    assert table.columns[-2] == "extrapolates" and not table["extrapolates"].any()
    assert f"all {len(table)} predictions within what the model was trained on" in stdout


def test_a_period_far_longer_than_trained_is_flagged(run_cli, study_dir, data, tmp_path):
    import cv2

    from roughsense.model.peak_law.law import PeakPowerLaw
    from roughsense.sensor.spectrum import SpatialSpectrum
    from tests.analysis.test_dataset import grating

    out = tmp_path / "law.json"
    assert fit(run_cli, study_dir, out, "--condition", "1N", "--model", "peak-law")[0] == 0
    ungated(out)  # a drawn grating far longer than trained: the band flag, not the gate, is tested here
    rng = np.random.default_rng(7)
    images = []
    for name, period_mm in (("trained_3mm.png", 3.0), ("long_9mm.png", 9.0)):  # trained: 1.5-5 mm
        images.append(tmp_path / name)
        assert cv2.imwrite(str(images[-1]), grating(period_mm, 1.0, rng))
    pred = tmp_path / "p.csv"
    code, stdout, err = run_cli("predict", out, *images, "--out", pred)
    assert code == 0, err
    table = pd.read_csv(pred)
    assert list(table["extrapolates"]) == [False, True]
    said = " ".join(stdout.split())  # wrapped to the terminal
    assert "1 of 2 predictions lies outside what the model was trained on; the `outside` column says how" in said
    assert "period 9." in table["outside"][1]  # the band's edge (a 30 mm line) or the trained range: a real period
    X, y, meta = data("1N")
    law = PeakPowerLaw(freq_per_mm=grid_per_mm()).fit(X, y, surfaces=meta["specimen"])
    spectra = SpatialSpectrum(px_per_mm=20.0, roi=(0, 16, 600, 32)).fit().transform(images)
    np.testing.assert_allclose(roughness(table), law.predict(spectra), rtol=RTOL_3_DIGITS)
    long_features = law.features(spectra[1:])[0]
    assert np.exp(long_features[0]) < np.exp(law.feature_min_[0])  # its peak is below the lowest trained frequency
    # ... so it is predicted as if at the edge of the law's domain: the law at the clipped features
    from roughsense.model.readout_domain import domain_margins

    low, high = domain_margins(float(np.diff(grid_per_mm())[0]), law.feature_min_, law.feature_max_)
    edge = np.exp(law.intercept_ + np.clip(long_features, low, high) @ law.coef_)
    assert roughness(table)[1] == pytest.approx(edge, rel=RTOL_3_DIGITS)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--model", "peak-law", "--max-components", "3"), "--max-components chooses PLS components"),
        (("--model", "peak-law", "--rule", "min"), "--rule chooses PLS components"),
        (("--model", "ridge"), "--model must be one of pls, peak-law, groove, got 'ridge'"),
        (("--model", "peak-law", "--cv", "40"), "K-fold needs 2 <= k <= n_samples=18"),
    ],
)
def test_fit_model_options_are_refused_in_one_line(run_cli, study_dir, tmp_path, args, message):
    out = tmp_path / "m.json"
    code, _, err = fit(run_cli, study_dir, out, "--condition", "1N", *args)
    _one_line(code, err, message)
    assert not out.exists()


def test_live_mode_counts_the_frames_that_extrapolate(run_cli, study_dir, tmp_path):
    import cv2

    from tests.analysis.test_dataset import grating

    model = tmp_path / "law.json"
    assert fit(run_cli, study_dir, model, "--condition", "1N", "--model", "peak-law")[0] == 0
    ungated(model)  # synthetic frames unlike its training presses on purpose: the gate is tested elsewhere
    rng = np.random.default_rng(8)
    video = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10, (600, 64))
    for period_mm in (3.0, 9.0, 9.0):  # trained periods span 1.5-5 mm
        writer.write(cv2.cvtColor(grating(period_mm, 1.0, rng), cv2.COLOR_GRAY2BGR))
    writer.release()
    code, out, err = run_cli("predict", model, "--live", "--source", video)
    assert code == 0, err
    assert "3 update(s)" in out
    assert "2 frame(s) extrapolated: outside what the model was trained on" in out


# --------------------------------------------------------------------------- images the model's crop or scale does not fit


SAMPLES = sorted((Path(roughsense.__file__).parent / "data" / "samples").glob("synthetic_grating_*"))


@pytest.fixture(scope="module")
def paper_scale_study(simulated_tiny):
    """A small simulated study read as ``builtin`` is: the paper's 34.9 px/mm and centred 1900x150 crop (shared)."""
    return simulated_tiny


def test_every_shipped_sample_scores_with_roi_auto(run_cli, paper_scale_study, tmp_path):
    from roughsense.sensor.spectrum import SpatialSpectrum

    assert len(SAMPLES) == 5
    model = tmp_path / "m.json"
    assert run_cli("fit", "--study", paper_scale_study, "--pad", "smooth", "--condition", "2N", "--max-components", "2",
                   "--model", "pls", "--out", model)[0] == 0
    ungated(model)  # the shipped samples are drawings, not contact images: the gate would withhold them
    document = json.loads(model.read_text())
    assert document["features"]["spectrum"]["roi"] == "center" and document["features"]["spectrum"]["px_per_mm"] == 34.9
    small = next(p for p in SAMPLES if "2.5mm" in p.name)  # 640x200: the model's 1900x150 crop does not fit
    code, _, err = run_cli("predict", model, small)
    _one_line(code, err, small.name, "--roi auto")
    pred = tmp_path / "p.csv"
    code, _, err = run_cli("predict", model, "--roi", "auto", *SAMPLES, "--out", pred)
    assert code == 0, err
    # the first sample is 640 px wide: 18.3 mm of line against the model's 54.4 mm, said in one warning line
    warned = [line for line in err.splitlines() if "--roi auto reads" in line]
    assert len(warned) == 1 and "warning" in warned[0] and "18.3 mm" in warned[0] and "54.4 mm (-66%)" in warned[0]
    full = next(p for p in SAMPLES if "1920x1080" in p.name)  # the model's own field: no warning
    code, _, err = run_cli("predict", model, "--roi", "auto", full)
    assert code == 0 and "--roi auto reads" not in err, err
    table = pd.read_csv(pred)
    assert list(table["image"]) == [str(p) for p in SAMPLES] and set(table["roi"]) == {"auto"}
    assert np.isfinite(roughness(table)).all()
    # the model's own spectrum (34.9 px/mm, its band), read at each sample's most textured band
    study = read_study(paper_scale_study)
    X, meta = dataset.condition_matrix(dataset.study_features(study), "smooth", "2N")
    y = dataset.targets(meta, dataset.perceived_roughness(study))
    spectra = SpatialSpectrum(px_per_mm=34.9, roi="auto").fit().transform(SAMPLES)
    expected = SIMPLS(document["model"]["n_components"]).fit(X, y).predict(spectra)
    np.testing.assert_allclose(roughness(table), expected, rtol=RTOL_3_DIGITS)


def test_fit_roi_replaces_the_study_roi_in_the_model(run_cli, study_dir, tmp_path):
    from roughsense.sensor.spectrum import SpatialSpectrum

    model = tmp_path / "m.json"
    code, stdout, err = fit(run_cli, study_dir, model, "--condition", "1N", "--max-components", "3", "--roi", "AUTO")
    assert code == 0, err
    assert "line read at --roi auto (the study's [sensor] roi: 0,16,600,32)" in stdout
    document = json.loads(model.read_text())
    assert document["features"]["spectrum"]["roi"] == "auto" and document["training"]["study_roi"] == [0, 16, 600, 32]
    study = read_study(study_dir)
    spectrum = SpatialSpectrum(px_per_mm=20.0, roi="auto").fit()
    X, meta = dataset.condition_matrix(dataset.study_features(study, spectrum=spectrum), "fingerprint", "1N")
    y = dataset.targets(meta, dataset.perceived_roughness(study))
    assert document["training"]["cv_rmse"] == pytest.approx(pls_cv(X, y, max_components=3).rmse.tolist(), rel=1e-12)
    code, _, err = run_cli("predict", model, study_dir / meta["image"][4], "--out", tmp_path / "p.csv")
    assert code == 0, err  # predict reads the line where the model says: auto
    k = document["model"]["n_components"]
    assert roughness(pd.read_csv(tmp_path / "p.csv"))[0] == pytest.approx(SIMPLS(k).fit(X, y).predict(X[4:5])[0],
                                                                            rel=RTOL_3_DIGITS)
    code, _, err = fit(run_cli, study_dir, tmp_path / "bad.json", "--condition", "1N", "--roi", "1,2,3")
    _one_line(code, err, "--roi", "X,Y,W,H")
    assert not (tmp_path / "bad.json").exists()


def _grating_at(px_per_mm: float, wavelength_mm: float, width_px: int, path):
    """A clean grating of ``wavelength_mm`` drawn at ``px_per_mm`` (as another camera would see the surface)."""
    import cv2

    x_mm = np.arange(width_px) / px_per_mm
    line = 0.5 + 0.2 * np.sign(np.sin(2 * np.pi * x_mm / wavelength_mm + 0.3))
    assert cv2.imwrite(str(path), np.round(255 * np.tile(line, (64, 1))).astype(np.uint8))
    return path


def test_predict_px_per_mm_scores_images_at_their_own_scale(run_cli, study_dir, tmp_path):
    from roughsense.model.modelfile import load_model
    from roughsense.sensor.spectrum import SpatialSpectrum

    model = tmp_path / "m.json"
    assert fit(run_cli, study_dir, model, "--condition", "1N", "--max-components", "3")[0] == 0  # 20 px/mm, 600 px
    ungated(model)  # another scale, a drawing: the gate (tests/model/test_press_gate.py) would withhold it
    at_20 = _grating_at(20.0, 2.0, 600, tmp_path / "at20.png")
    at_40 = _grating_at(40.0, 2.0, 1200, tmp_path / "at40.png")  # the same surface, twice the resolution
    code, _, err = run_cli("predict", model, at_20, "--out", tmp_path / "a.csv")
    assert code == 0, err
    code, stdout, err = run_cli("predict", model, at_40, "--px-per-mm", "40", "--roi", "0,16,1200,32",
                                "--out", tmp_path / "b.csv")
    assert code == 0, err
    native, scaled = pd.read_csv(tmp_path / "a.csv"), pd.read_csv(tmp_path / "b.csv")
    assert list(scaled.columns[5:8]) == ["roi", "px_per_mm", "roughness_rel_R3"]
    assert scaled["roi"][0] == "0,16,1200,32" and scaled["px_per_mm"][0] == 40.0 and native["px_per_mm"][0] == 20.0
    loaded = load_model(model)
    line_at_40 = SpatialSpectrum(px_per_mm=40.0, roi=(0, 16, 1200, 32)).fit().transform([at_40])
    assert roughness(scaled)[0] == pytest.approx(loaded.predict(line_at_40)[0], rel=RTOL_3_DIGITS)
    # in mm^-1 the two cameras see one spectrum, so one roughness; read at the model's 20 px/mm it looks 4 mm
    assert roughness(scaled)[0] == pytest.approx(roughness(native)[0], rel=0.02)
    code, _, err = run_cli("predict", model, at_40, "--roi", "0,16,1200,32", "--out", tmp_path / "c.csv")
    assert code == 0, err
    assert abs(roughness(pd.read_csv(tmp_path / "c.csv"))[0] - roughness(native)[0]) > 0.2
    # scales at which the model's band cannot be measured
    code, _, err = run_cli("predict", model, at_20, "--px-per-mm", "1.5")
    _one_line(code, err, "--px-per-mm 1.5", "Nyquist frequency 0.75 mm^-1")
    code, _, err = run_cli("predict", model, at_20, "--px-per-mm", "100", "--roi", "auto")
    _one_line(code, err, "at20.png", "6 mm long (600 px at 100 px/mm), shorter than 1/f_min = 10 mm")
    code, _, err = run_cli("predict", model, at_20, "--px-per-mm", "-2")
    _one_line(code, err, "--px-per-mm must be a positive number")


@pytest.mark.parametrize(("typed", "stored"), [("2n", "2N"), (" 2N ", "2N"), ("Combined", "combined")])
def test_fit_condition_ignores_case(run_cli, study_dir, tmp_path, typed, stored):
    out = tmp_path / "m.json"
    code, stdout, err = fit(run_cli, study_dir, out, "--condition", typed, "--max-components", "2")
    assert code == 0, err
    document = json.loads(out.read_text())
    assert document["training"]["condition"] == stored and f"pad fingerprint, {stored}, " in stdout
    forces = ["1N", "2N", "3N"] if stored == "combined" else [stored]
    assert document["features"]["conditions"] == forces


def test_counts_agree_with_their_nouns(run_cli, study_dir, tmp_path):
    code, stdout, err = fit(run_cli, study_dir, tmp_path / "m.json", "--condition", "1N", "--max-components", "1")
    assert code == 0, err
    chosen = json.loads((tmp_path / "m.json").read_text())["model"]["n_components"]
    assert chosen == 1 and "chosen: 1 component (" in stdout and "1 components" not in stdout
    image = next((study_dir / "images").glob("*_1N_1.png"))
    code, stdout, err = run_cli("predict", tmp_path / "m.json", image, "--out", tmp_path / "p.csv")
    assert code == 0 and "wrote 1 prediction to" in stdout
    assert [counted(n, "specimen") for n in (0, 1, 2)] == ["0 specimens", "1 specimen", "2 specimens"]


def test_predict_study_table_fits_80_columns(run_cli, study_dir, tmp_path, monkeypatch):
    model = tmp_path / "c.json"
    assert fit(run_cli, study_dir, model, "--condition", "combined", "--max-components", "2")[0] == 0
    monkeypatch.setenv("COLUMNS", "80")
    code, stdout, err = run_cli("predict", model, "--study", study_dir)
    assert code == 0, err
    lines = stdout.splitlines()
    assert max(len(line) for line in lines) <= 80, stdout
    assert not any(line.endswith("\\") for line in lines), stdout  # one line per row, no continuation block
    assert lines[0].startswith("pad fingerprint, condition combined") and "--out" in " ".join(lines[:3])
    code, _, err = run_cli("predict", model, "--study", study_dir, "--out", tmp_path / "p.csv")
    assert code == 0, err
    table = pd.read_csv(tmp_path / "p.csv")  # every value the terminal shows, row by row
    header = next(i for i, line in enumerate(lines) if line.split()[:2] == ["specimen", "repetition"])
    first = [str(table["specimen"][0]), str(table["repetition"][0])]  # headers wider than their column wrap
    start = next(i for i, line in enumerate(lines) if i > header and line.split()[:2] == first)
    rows = [line.split() for line in lines[start:start + len(table)]]
    assert [r[:2] for r in rows] == [[s, str(r)] for s, r in zip(table["specimen"], table["repetition"])]
    assert [float(r[2]) for r in rows] == pytest.approx(list(roughness(table)), rel=1e-5)


def test_fit_refuses_a_study_whose_images_are_all_the_same(run_cli, study_dir, tmp_path):
    """Issue 22, item 6: copies of one image gave a one-component model of rounding noise, though its own CV
    curve was worse than no components. Now one line naming the manifest, exit 2, no model file."""
    import shutil

    same = shutil.copytree(study_dir, tmp_path / "same")
    images = sorted((same / "images").rglob("*.png"))
    assert len(images) > 10
    for image in images[1:]:
        shutil.copyfile(images[0], image)
    out = tmp_path / "m.json"
    for condition in ("1N", "combined"):
        for model in ("pls", "peak-law"):  # the law, too: a constant law would still "beat" the arithmetic mean
            code, stdout, err = fit(run_cli, same, out, "--condition", condition, "--model", model)
            _one_line(code, err, str(same / "manifest.csv"), "has the same spectrum")
    assert not out.exists()


def test_a_pls_model_no_better_than_the_training_mean_is_refused():
    """The CV curve decides: when every component count predicts held-out trials worse than the training mean,
    the spectra carry nothing about the ratings, and fit writes no model (a study of noise spectra)."""
    from roughsense.model.pls.training import _refuse_no_better_than_mean

    rng = np.random.default_rng(4)
    X, y = rng.random((24, 30)), rng.random(24)  # independent: nothing to learn
    result = pls_cv(X, y, max_components=4)
    assert result.rmse[1:].min() >= result.rmse[0]  # the premise, from the CV itself
    with pytest.raises(InputError, match=r"no PLS component count beats the training mean .* with none"):
        _refuse_no_better_than_mean(result, "pad 'x' at 1N", Path("manifest.csv"))
    learnable = pls_cv(X, X[:, :3].sum(axis=1), max_components=4)  # y in X's span: components help
    _refuse_no_better_than_mean(learnable, "pad 'x' at 1N", Path("manifest.csv"))


def test_fit_judges_the_model_for_unseen_surfaces_and_predict_repeats_a_failure(run_cli, study_dir, tmp_path):
    """Issue 27: whatever --cv, the model is judged as the study judges it (nested LOSO against the training mean
    and shuffled targets); the file records it with the 90 % interval, and a failure is one line in fit and predict."""
    for model in ("peak-law", "pls"):
        out = tmp_path / f"{model}.json"
        code, stdout, err = fit(run_cli, study_dir, out, "--condition", "2N", "--model", model)
        assert code == 0, err
        training = json.loads(out.read_text())["training"]
        unseen = training["unseen"]
        assert unseen["cv"] == "loso (nested)" and unseen["n_permutations"] == 199
        assert "a grating left out of training (nested leave-one-specimen-out): per-specimen RMSE" in stdout
        warned = [line for line in err.splitlines() if "FAILS its controls" in line]
        assert bool(warned) == (not unseen["passes_controls"]) == bool(unseen["failure"])
        assert len(warned) <= 1 and (not warned or warned[0].endswith(unseen["failure"]))
        assert training["interval"]["level"] == 0.9 and training["target_range"][0] > 0
        code, _, predicted_err = run_cli("predict", out, "--study", study_dir, "--out", tmp_path / f"{model}.csv")
        assert code == 0, predicted_err
        assert [line for line in predicted_err.splitlines() if "FAILS its controls" in line] == warned
        table = pd.read_csv(tmp_path / f"{model}.csv", dtype=str)
        assert set(table["model"]) == {model}
        for column in ("roughness_rel_R3", "jackknife90_low", "jackknife90_high", "surface_roughness_rel_R3"):
            if column in table:  # 3 significant digits, and positive
                assert all(len(v.lstrip("0.").replace(".", "").split("e")[0]) <= 3 for v in table[column]), column
                assert (table[column].astype(float) > 0).all()
        assert "pi90_low" not in table  # a press read with its surface's others: the plain jackknife, named so
        assert (table["jackknife90_low"].astype(float) < table["roughness_rel_R3"].astype(float)).all() \
            if "jackknife90_low" in table else training["interval"]["trial_log_halfwidth"] is None


def test_a_press_read_alone_gets_the_interval_calibrated_for_reading_alone(run_cli, study_dir, data, tmp_path):
    """Issue 27, then 35: bare images are read one by one, which the peak law does less surely than a surface's
    presses together. The file keeps the jackknife+ over specimens (a press read alone is a surface of one press),
    unbounded from this study's 6 specimens; then, and for a file written before the jackknife+, predict falls back
    to the plain jackknife calibrated for reading alone, saying so and why once."""
    import itertools
    import math

    from roughsense.model.modelfile import _digest

    model = tmp_path / "law.json"
    assert fit(run_cli, study_dir, model, "--condition", "1N", "--model", "peak-law")[0] == 0
    document = json.loads(model.read_text())
    assert sorted(document["training"]["jackknife_plus"]["specimens"]) == sorted(SPECIMENS)
    _, _, meta = data("1N")
    images = [study_dir / name for name in meta["image"][:3]]
    del document["training"]["jackknife_plus"]  # as written before it existed, checksum and all
    document["sha256"] = _digest(document)
    old = tmp_path / "old.json"
    old.write_text(json.dumps(document))
    interval = document["training"]["interval"]
    said = {model: "roughsense: warning: the jackknife+ over specimens (6) needs at least 9 training specimens for a "
                   "90 % interval: these intervals are the plain jackknife (no coverage guarantee), where it has one",
            old: "roughsense: warning: this model file keeps no leave-one-specimen-out fold models (written before they "
                 "were kept): its intervals are the plain jackknife (no coverage guarantee); refit it with roughsense "
                 "fit for the jackknife+ over specimens"}
    for path, (extra, width) in itertools.product((model, old), (((), interval["alone_log_halfwidth"]),
                                                               (("--same-surface",), interval["trial_log_halfwidth"]))):
        code, _, err = run_cli("predict", path, *images, *extra, "--out", tmp_path / "p.csv", "--force")
        assert code == 0, err
        assert [line for line in err.splitlines() if "plain jackknife" in line] == [said[path]]
        table = pd.read_csv(tmp_path / "p.csv")
        ratio = table["jackknife90_high"] / roughness(table)
        np.testing.assert_allclose(ratio, math.exp(width), rtol=0.02)  # 3 significant digits each
        assert not [c for c in table.columns if "pi90" in c]  # the plain jackknife is never named pi90
        assert ("surface_roughness_rel_R3" in table) == bool(extra)
        assert set(table["px_per_mm"]) == {20.0}  # the scale read at, alone or as one surface


def test_a_live_frame_says_why_it_lies_outside_as_predict_says_for_its_image(run_cli, study_dir, tmp_path):
    """Live mode flagged a frame finer than the band as "outside the training range"; it now carries the reason
    predict gives the same image read alone (model/outside.domain_reasons), to the display and the summary line."""
    import cv2

    from roughsense.model.modelfile import load_model
    from roughsense.model.scoring import frame_scorer, score_trials

    model = tmp_path / "law.json"
    assert fit(run_cli, study_dir, model, "--condition", "1N", "--model", "peak-law")[0] == 0
    ungated(model)  # synthetic frames unlike its training presses on purpose: the gate is tested elsewhere
    fine = _grating_at(20.0, 0.5, 600, tmp_path / "fine_1N.png")  # 0.5 mm: finer than the band's 1 mm
    loaded = load_model(model)
    scores = score_trials(loaded, [fine])
    [expected] = scores.reasons
    assert expected.startswith("finer than the sensor resolves: period 0.50 mm")
    frame = cv2.cvtColor(cv2.imread(str(fine)), cv2.COLOR_BGR2RGB)
    score, reason = frame_scorer(loaded)(frame)
    assert reason == expected and score == pytest.approx(float(scores.roughness[0]), rel=1e-9)
    assert frame_scorer(loaded)(cv2.cvtColor(cv2.imread(str(_grating_at(20.0, 3.0, 600, tmp_path / "g.png"))),
                                             cv2.COLOR_BGR2RGB))[1] == ""  # a 3 mm grating lies inside

    _grating_at(20.0, 0.5, 600, tmp_path / "frame_0.png")
    code, stdout, err = run_cli("predict", model, "--live", "--source", str(tmp_path / "frame_%d.png"),
                                "--max-frames", "1")
    assert code == 0, err
    assert f"1 frame(s) extrapolated: outside what the model was trained on; the last: {expected}" in stdout


def test_the_domain_line_of_a_law_that_reads_the_shape_states_its_contact_patterns():
    """A 3-feature law flags a press by its contact pattern too ("trained surfaces 0.23-0.49 of the period in
    contact"); fit's line stating the domain said only the periods. A law that reads no shape says none."""
    from types import SimpleNamespace

    from roughsense.model.peak_law.training import _shape_range
    from roughsense.sensor.shape import duty_cycle

    shaped = SimpleNamespace(feature_min_=np.array([-1.6, 1.4, -3.8]), feature_max_=np.array([-0.7, 3.0, -0.3]))
    assert _shape_range(shaped) == (f" and contact patterns {duty_cycle(-0.3):.2f}-{duty_cycle(-3.8):.2f} of the "
                                    "period in contact")
    assert duty_cycle(-0.3) < duty_cycle(-3.8)  # a larger second harmonic: narrower contact
    unread = SimpleNamespace(feature_min_=np.array([-1.6, 1.4, np.nan]), feature_max_=np.array([-0.7, 3.0, np.nan]))
    assert _shape_range(unread) == "" and _shape_range(SimpleNamespace(feature_min_=np.zeros(2),
                                                                        feature_max_=np.ones(2))) == ""
