"""``roughsense fit`` and ``roughsense predict`` end to end on a tiny synthetic study, and their bad inputs."""
from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

from roughsense import SIMPLS, dataset, pls_cv
from roughsense.study import read_study
from tests.test_dataset import make_study


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


def fit(run_cli, study_dir, out, *extra):
    return run_cli("fit", "--study", study_dir, "--pad", "fingerprint", "--out", out, *extra)


def test_fit_chooses_the_cv_minimum_and_stores_the_curve(run_cli, study_dir, data, tmp_path):
    out = tmp_path / "m.json"
    code, stdout, err = fit(run_cli, study_dir, out, "--condition", "2N", "--max-components", "6")
    assert code == 0, err
    X, y, _ = data("2N")
    expected = pls_cv(X, y, max_components=6, cv="loo")
    k = expected.best_n_components
    assert f"chosen: {k} components" in stdout
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
    assert list(table.columns) == ["image", "roughness"] and len(table) == len(images)
    np.testing.assert_allclose(table["roughness"], SIMPLS(k).fit(X, y).predict(X), rtol=1e-12)

    code, stdout, err = run_cli("predict", out, images[0], images[5])
    assert code == 0, err
    assert "roughness" in stdout and images[5].name in stdout
    assert f"{table['roughness'][5]:.6g}" in stdout


def test_combined_model_takes_trials_of_three(run_cli, study_dir, data, tmp_path):
    out = tmp_path / "combined.json"
    code, stdout, err = fit(run_cli, study_dir, out, "--condition", "combined", "--max-components", "5", "--cv", "loso")
    assert code == 0, err
    X, y, meta = data("combined")
    assert X.shape == (18, 135)
    expected = pls_cv(X, y, max_components=5, groups=meta["specimen"].to_numpy())
    assert f"chosen: {expected.best_n_components} components" in stdout
    assert "leave-one-group-out" in stdout
    images = [study_dir / meta[f"image_{f}"][i] for i in (0, 7) for f in ("1N", "2N", "3N")]
    pred = tmp_path / "p.csv"
    code, _, err = run_cli("predict", out, *images, "--out", pred)
    assert code == 0, err
    table = pd.read_csv(pred)
    assert list(table.columns) == ["image_1N", "image_2N", "image_3N", "roughness"] and len(table) == 2
    refit = SIMPLS(expected.best_n_components).fit(X, y).predict(X[[0, 7]])
    np.testing.assert_allclose(table["roughness"], refit, rtol=1e-12)
    code, _, err = run_cli("predict", out, *images[:4])
    assert code == 2
    assert "groups of 3" in err and "not a multiple of 3" in err
    assert "Traceback" not in err


def test_one_se_rule(run_cli, study_dir, data, tmp_path):
    out = tmp_path / "m.json"
    code, stdout, err = fit(run_cli, study_dir, out, "--condition", "3N", "--cv", "loso", "--rule", "1se", "--max-components", "6")
    assert code == 0, err
    X, y, meta = data("3N")
    expected = pls_cv(X, y, max_components=6, groups=meta["specimen"].to_numpy())
    assert f"chosen: {expected.one_se_n_components} components" in stdout
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
    assert code == 0 and "groups of three: 1N, 2N, 3N" in text
