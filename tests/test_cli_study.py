"""``roughsense study`` end to end on a small simulated study, and its bad-input contract."""
from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

from roughsense.sim.simulate import SimulationConfig, simulate_study, with_image_size

SPECIMENS = ("R2", "R3", "C3", "C5")


def _simulate(root, *, repetitions: int):
    config = SimulationConfig(pads=("smooth",), specimens=SPECIMENS, repetitions=repetitions, seed=11,
                              participants=4, sessions=2)
    simulate_study(root, with_image_size(config, 1920, 170), jobs=1)
    return root


@pytest.fixture(scope="module")
def small_study(tmp_path_factory):
    return _simulate(tmp_path_factory.mktemp("study") / "study", repetitions=3)


@pytest.fixture()
def study_copy(small_study, tmp_path):
    return shutil.copytree(small_study, tmp_path / "copy")


def test_study_command_writes_the_report(run_cli, small_study, tmp_path, monkeypatch):
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    out = tmp_path / "report"
    code, stdout, err = run_cli("study", "--data", small_study, "--out", out, "--max-components", "4")
    assert code == 0, err
    results = pd.read_csv(out / "results.csv")
    assert len(results) == len(SPECIMENS) * 4
    assert set(results["condition"]) == {"1N", "2N", "3N", "combined"}
    # Per-specimen RMSE is never below the spread of the predictions about their mean (RMSE^2 = bias^2 + SD^2).
    assert np.all(results["rmse"] + 1e-12 >= results["pred_sd"])
    assert set(pd.read_csv(out / "results_loso.csv")["specimen"]) == set(SPECIMENS)
    tests = pd.read_csv(out / "tests.csv")
    assert set(tests["comparison"]) == {"smooth: combined vs 1N", "smooth: combined vs 2N", "smooth: combined vs 3N"}
    assert (tests["p_adjusted"] >= tests["p"]).all()
    assert "Report written to" in stdout
    # A second run reuses the feature cache and gives the same numbers.
    code, stdout2, err = run_cli("study", "--data", small_study, "--out", out, "--max-components", "4", "--force")
    assert code == 0, err
    pd.testing.assert_frame_equal(pd.read_csv(out / "results.csv"), results)


def test_study_refuses_a_non_empty_report_folder(run_cli, small_study, tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "draft.txt").write_text("mine")
    code, _, err = run_cli("study", "--data", small_study, "--out", out)
    assert code == 2 and "--force" in err and str(out) in err
    assert sorted(p.name for p in out.iterdir()) == ["draft.txt"]


def test_study_with_a_missing_file_names_it(run_cli, study_copy, tmp_path):
    (study_copy / "ratings.csv").unlink()
    code, _, err = run_cli("study", "--data", study_copy, "--out", tmp_path / "r")
    assert code == 2 and "ratings.csv" in err and err.count("\n") == 1
    assert not (tmp_path / "r").exists()


def test_study_with_a_missing_image_names_the_row(run_cli, study_copy, tmp_path):
    manifest = pd.read_csv(study_copy / "manifest.csv")
    (study_copy / manifest["image"].iloc[4]).unlink()
    code, _, err = run_cli("study", "--data", study_copy, "--out", tmp_path / "r")
    assert code == 2 and "manifest.csv, row 6" in err and "image file not found" in err


def test_study_with_ratings_for_an_unknown_specimen_names_the_row(run_cli, study_copy, tmp_path):
    ratings = study_copy / "ratings.csv"
    lines = ratings.read_text().splitlines()
    lines.append("P1,1,X9,1.2")
    ratings.write_text("\n".join(lines) + "\n")
    code, _, err = run_cli("study", "--data", study_copy, "--out", tmp_path / "r")
    assert code == 2 and f"ratings.csv, row {len(lines)}" in err and "X9" in err


def test_study_with_too_few_repetitions_says_so(run_cli, tmp_path, monkeypatch):
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    study = _simulate(tmp_path / "one-rep", repetitions=1)
    code, _, err = run_cli("study", "--data", study, "--out", tmp_path / "r")
    assert code == 2 and "too few repetitions" in err and "manifest.csv" in err
    assert not (tmp_path / "r").exists()
