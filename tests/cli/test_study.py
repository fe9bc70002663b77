"""``roughsense study`` end to end on a small simulated study, and its bad-input contract."""
from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

from roughsense.model.registry import names as family_names
from roughsense.report.control_tables import permutation_p_text
from roughsense.sim.config import SimulationConfig, with_image_size
from roughsense.sim.simulate import simulate_study
from tests.commands import HUGE, error_line, refusal_line

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


def test_study_command_writes_the_report(run_cli, small_study, tmp_path, monkeypatch, quick_figures):
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    out = tmp_path / "report"
    code, stdout, err = run_cli("study", "--study", small_study, "--out", out, "--max-components", "4")
    assert code == 0, err
    results = pd.read_csv(out / "results.csv")
    assert len(results) == len(SPECIMENS) * 4 * len(family_names()) and list(results.columns)[-1] == "model"
    assert (results.groupby("model").size() == len(SPECIMENS) * 4).all()
    assert set(results["model"]) == set(family_names())
    assert set(results["condition"]) == {"1N", "2N", "3N", "combined"}
    # Per-specimen RMSE is never below the spread of the predictions about their mean (RMSE^2 = bias^2 + SD^2).
    assert np.all(results["rmse"] + 1e-12 >= results["pred_sd"])
    assert set(pd.read_csv(out / "results_loso.csv")["specimen"]) == set(SPECIMENS)
    tests = pd.read_csv(out / "tests.csv")
    assert set(tests["comparison"]) == {"smooth: combined vs 1N", "smooth: combined vs 2N", "smooth: combined vs 3N"}
    assert (tests["p_adjusted"] >= tests["p"]).all()
    assert "Report written to" in stdout
    # A folder the simulator wrote is labelled simulated (with its seed) even when passed with --study.
    html = (out / "index.html").read_text()
    assert "simulated: simulated study (digital twin), simulation seed 11" in html and "user data" not in html
    controls = pd.read_csv(out / "controls.csv")
    assert len(controls) == 4 * 2 * len(family_names()) and (controls["n_permutations"] == 199).all()
    _check_unseen_lines(stdout, out)
    # A second run reuses the feature cache and gives the same numbers (the controls, which results.csv does not
    # hold, are left out of it).
    code, stdout2, err = run_cli("study", "--study", small_study, "--out", out, "--max-components", "4", "--force",
                                 "--permutations", "0")
    assert code == 0, err
    pd.testing.assert_frame_equal(pd.read_csv(out / "results.csv"), results)
    assert "<dd>from cache</dd>" in (out / "index.html").read_text()


def _check_unseen_lines(stdout: str, out) -> None:
    """The terminal summary opens with surfaces never seen: a headline, then one line per pad, from the report's data."""
    lines = stdout.splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("Held-out surfaces"))
    assert "leave-one-specimen-out, combined" in lines[first]
    assert lines[first + 1].startswith("  smooth pad: pls ") and "/ peak-law " in lines[first + 1]
    assert first + 1 < next(i for i, line in enumerate(lines) if "(pls, LOO)" in line)  # before the paper's LOO lines
    loso = pd.read_csv(out / "results_loso.csv").query("condition == 'combined'")
    for model in ("pls", "peak-law"):
        assert f"{model} {loso[loso.model == model]['rmse'].mean():.2f} (p " in lines[first + 1]
    controls = pd.read_csv(out / "controls.csv").query("cv == 'loso' and condition == 'combined'")
    peak = controls.set_index("model").loc["peak-law"]
    p = permutation_p_text(peak["permutation_p"], peak["n_permutations"], at_most="<=")
    assert f"p {p}" in lines[first + 1] and "p 0.000" not in stdout


def test_study_refuses_a_non_empty_report_folder(run_cli, small_study, tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "draft.txt").write_text("mine")
    code, _, err = run_cli("study", "--study", small_study, "--out", out)
    assert code == 2 and "--force" in err and str(out) in err
    assert sorted(p.name for p in out.iterdir()) == ["draft.txt"]


def test_study_with_a_missing_file_names_it(run_cli, study_copy, tmp_path):
    (study_copy / "ratings.csv").unlink()
    code, _, err = run_cli("study", "--study", study_copy, "--out", tmp_path / "r")
    assert code == 2 and "ratings.csv" in err and err.count("\n") == 1
    assert err.rstrip().endswith(f"run `roughsense check {study_copy}` to list every problem")
    assert not (tmp_path / "r").exists()


def test_study_with_a_missing_image_names_the_row(run_cli, study_copy, tmp_path):
    manifest = pd.read_csv(study_copy / "manifest.csv")
    (study_copy / manifest["image"].iloc[4]).unlink()
    code, _, err = run_cli("study", "--study", study_copy, "--out", tmp_path / "r")
    assert code == 2 and "manifest.csv, row 6" in err and "image file not found" in err


def test_study_with_ratings_for_an_unknown_specimen_names_the_row(run_cli, study_copy, tmp_path):
    ratings = study_copy / "ratings.csv"
    lines = ratings.read_text().splitlines()
    lines.append("P1,1,X9,1.2")
    ratings.write_text("\n".join(lines) + "\n")
    code, _, err = run_cli("study", "--study", study_copy, "--out", tmp_path / "r")
    assert code == 2 and f"ratings.csv, row {len(lines)}" in err and "X9" in err


def test_study_with_too_few_repetitions_says_so(run_cli, tmp_path, monkeypatch):
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    study = _simulate(tmp_path / "one-rep", repetitions=1)
    code, _, err = run_cli("study", "--study", study, "--out", tmp_path / "r")
    assert code == 2 and "too few repetitions" in err and "manifest.csv" in err
    assert not (tmp_path / "r").exists()


def _video_of(images, path, size=None):
    import cv2

    first = cv2.imread(str(images[0]))
    height, width = first.shape[:2] if size is None else size
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (width, height))
    for image in images:
        frame = cv2.imread(str(image))
        writer.write(cv2.resize(frame, (width, height)) if size is not None else frame)
    writer.release()
    return path


def test_predict_live_scores_a_video_like_the_still_images(run_cli, small_study, tmp_path):
    from tests.model.test_gate_file import ungated

    model = tmp_path / "m.json"
    code, _, err = run_cli("fit", "--study", small_study, "--pad", "smooth", "--condition", "2N",
                           "--max-components", "3", "--model", "pls", "--out", model)
    assert code == 0, err
    ungated(model)  # a compressed video's frames have smoothed noise: the gate (test_press_gate.py) would withhold
    manifest = pd.read_csv(small_study / "manifest.csv")
    images = [small_study / p for p in manifest.loc[manifest["nominal_force_n"] == 2.0, "image"].iloc[:4]]
    video = _video_of(images, tmp_path / "clip.avi")
    code, out, err = run_cli("predict", model, "--live", "--source", video, "--max-frames", "4")
    assert code == 0, err
    assert "4 update(s)" in out
    # The live score of the last frame is the still-image score of the same (JPEG-compressed) frame.
    code, _, err = run_cli("predict", model, images[-1], "--out", tmp_path / "still.csv")
    assert code == 0, err
    last_live = float(out.split("last roughness")[1].split()[0])
    last_still = float(pd.read_csv(tmp_path / "still.csv")["roughness_rel_R3"].iloc[0])
    assert last_live == pytest.approx(last_still, abs=0.05)


def test_predict_live_refuses_frames_that_do_not_fit_the_model(run_cli, small_study, tmp_path):
    model = tmp_path / "m.json"
    assert run_cli("fit", "--study", small_study, "--pad", "smooth", "--condition", "1N",
                   "--max-components", "2", "--model", "pls", "--out", model)[0] == 0
    manifest = pd.read_csv(small_study / "manifest.csv")
    video = _video_of([small_study / manifest["image"].iloc[0]] * 2, tmp_path / "small.avi", size=(120, 640))
    code, _, err = run_cli("predict", model, "--live", "--source", video, "--max-frames", "2")
    assert code == 2 and "small.avi" in err and "frame 1" in err and err.count("\n") == 1


def test_predict_live_needs_a_source_and_a_single_force_model(run_cli, small_study, tmp_path):
    model = tmp_path / "c.json"
    assert run_cli("fit", "--study", small_study, "--pad", "smooth", "--condition", "combined",
                   "--max-components", "2", "--model", "pls", "--out", model)[0] == 0
    code, _, err = run_cli("predict", model, "--live")
    assert code == 2 and "--source" in err
    code, _, err = run_cli("predict", model, "--live", "--source", tmp_path / "none.avi")
    assert code == 2 and "single-force" in err


def test_a_participant_missing_a_session_is_one_warning_line_and_in_the_report(run_cli, study_copy, tmp_path, monkeypatch):
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    ratings = pd.read_csv(study_copy / "ratings.csv", dtype=str)
    first = ratings.iloc[0]
    gap = (ratings.participant == first.participant) & (ratings.session == first.session)
    ratings[~gap].to_csv(study_copy / "ratings.csv", index=False)
    out = tmp_path / "r"
    code, _, err = run_cli("study", "--study", study_copy, "--out", out, "--max-components", "3", "--no-loso",
                           "--permutations", "0")  # the ratings' warning, not the controls
    assert code == 0, err
    warnings_lines = [line for line in err.splitlines() if line.startswith("roughsense: warning:")]
    assert warnings_lines and first.participant in warnings_lines[0]
    assert "Traceback" not in err and ".py:" not in err  # no raw Python warning with a source line
    assert first.participant in (out / "index.html").read_text().split("<dt>warnings</dt>")[1][:400]


def test_study_writes_its_figures_in_the_format_and_resolution_asked(run_cli, small_study, tmp_path):
    out = tmp_path / "svg"
    code, _, err = run_cli("study", "--study", small_study, "--out", out, "--max-components", "2", "--no-loso",
                           "--permutations", "0", "--figure-format", "SVG", "--dpi", "50")
    assert code == 0, err
    assert (out / "cv_curves.svg").is_file() and not list(out.glob("*.png"))
    for bad, needle in ((["--figure-format", "jpg"], "--figure-format must be one of png, svg, pdf"),
                        (["--dpi", "5"], "--dpi")):
        code, _, err = run_cli("study", "--study", small_study, "--out", tmp_path / "bad", *bad)
        assert code == 2 and needle in err and err.count("\n") == 1 and "Traceback" not in err
        assert not (tmp_path / "bad").exists()


def test_study_on_a_missing_folder_does_not_suggest_checking_it(run_cli, tmp_path):
    """Also seen: ``study --study missing`` suggested running check on the missing folder."""
    code, _, err = run_cli("study", "--study", tmp_path / "missing", "--out", tmp_path / "rep")
    assert code == 2 and error_line(err) == f"roughsense: error: {tmp_path / 'missing'}: study folder not found"


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    from roughsense.sim.config import SimulationConfig, with_image_size
    from roughsense.sim.simulate import simulate_study

    config = SimulationConfig(pads=("smooth",), specimens=("R2", "R3", "R4"), repetitions=1, seed=5, participants=3,
                              sessions=2)
    return simulate_study(tmp_path_factory.mktemp("noise") / "study", with_image_size(config, 1920, 170), jobs=1)


def test_a_huge_image_path_in_the_manifest_is_one_short_line(run_cli, study, tmp_path):
    root = shutil.copytree(study, tmp_path / "study")
    manifest = pd.read_csv(root / "manifest.csv", dtype=str, keep_default_na=False)
    manifest.loc[0, "image"] = "images/" + "a" * HUGE + ".png"
    manifest.to_csv(root / "manifest.csv", index=False)
    code, _, err = run_cli("study", "--study", root, "--out", tmp_path / "report")
    assert str(root) in refusal_line(code, err)
    assert len(err) < 2000


def test_a_camera_scale_below_nyquist_names_study_toml_and_the_key(run_cli, study, tmp_path):
    root = shutil.copytree(study, tmp_path / "study")
    toml = root / "study.toml"
    toml.write_text(toml.read_text().replace("px_per_mm = 34.9\n", "px_per_mm = 1.5\n", 1))
    code, _, err = run_cli("study", "--study", root, "--out", tmp_path / "report")
    assert refusal_line(code, err) == (
        f"roughsense: error: {toml}: [sensor] px_per_mm 1.5 is too coarse: its Nyquist frequency 0.75 mm^-1 is not "
        "above the band's f_max 1 mm^-1 (it must be above 2 px/mm)")


@pytest.mark.slow
def test_study_runs_on_gratings_whose_land_is_not_half_the_period(run_cli, tmp_path, quick_figures):
    """A study with rectangles of other lands at the paper's periods runs as the paper's does (pre-46 the paper's
    circle-vs-rectangle claim stopped it), and holds out each land/groove geometry on the first screen."""
    config = SimulationConfig(pads=("smooth",), specimens=("R2", "R3", "R4", "C2", "C3", "C4", "rect:2:1:0.6",
                                                           "rect:4:1:2.8"),
                              repetitions=2, seed=11, participants=4, sessions=2)
    simulate_study(tmp_path / "study", with_image_size(config, 1920, 170), jobs=1)
    code, out, err = run_cli("study", "--study", tmp_path / "study", "--out", tmp_path / "r", "--max-components", 2,
                             "--permutations", 0)
    assert code == 0, err
    held = pd.read_csv(tmp_path / "r" / "held_out.csv")
    geometry = held[held.scheme == "geometry"]
    assert set(geometry.held_out) == {"land 0.3", "land 0.5", "land 0.7"}
    assert "a land/groove geometry left out: land 0.7" in (tmp_path / "r" / "index.html").read_text()
    claims = (tmp_path / "r" / "claims.csv").read_text()
    assert "Circular gratings feel rougher" in claims and "rect_2_1_0.6" not in claims
