"""The sensor's scale and band: periods measured below the DFT's bin on lines of known period, the band test's verdicts,
``roughsense calibrate`` writing study.toml, and predict flagging a wrong scale or a surface outside the band."""
from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from roughsense.model.scale_check import SCALE_TOLERANCE, check_study_lines
from roughsense.sensor.band import DOMINANCE, BandReading, band_reading, band_reason, band_reasons
from roughsense.sensor.period import calibrate_scale, check_scale, strongest_peak

LINE_PX = 1900


def square_line(period_mm: float, px_per_mm: float, *, ridge_mm: float | None = None, phase: float = 0.3,
                noise: float = 0.0, seed: int = 0) -> np.ndarray:
    """A line across a grating of ``period_mm`` (lands bright, grooves dark), optionally with a pad's ridges."""
    x_mm = np.arange(LINE_PX) / px_per_mm
    line = 0.4 + 0.3 * (np.sin(2 * np.pi * x_mm / period_mm + phase) > 0)
    if ridge_mm is not None:
        line = line + 0.25 * np.cos(2 * np.pi * x_mm / ridge_mm + 1.1)
    return line + noise * np.random.default_rng(seed).standard_normal(LINE_PX)


@given(period_px=st.floats(8.0, 300.0), phase=st.floats(0.0, 6.28))
def test_a_sinusoid_reads_its_own_period_below_the_bin(period_px, phase):
    """The refined peak of a pure sinusoid is its frequency to 1e-4 of it (a DFT bin is 1/1900 cycles per px,
    0.5-16 % of these frequencies)."""
    line = np.sin(2 * np.pi * np.arange(LINE_PX) / period_px + phase)
    f = 1.0 / period_px
    found, _ = strongest_peak(line, 0.8 * f, 1.2 * f)
    assert found == pytest.approx(f, rel=1e-4 if period_px < 120 else 1e-3)


@pytest.mark.parametrize("px_per_mm", [20.0, 34.9, 47.3, 60.0])
@pytest.mark.parametrize("period_mm", [2.0, 3.0, 5.0])
@pytest.mark.parametrize("ridge_mm", [None, 1.0])
@pytest.mark.parametrize("searched", [None, (10, 120)])
def test_calibrate_recovers_the_scale_of_a_grating_with_or_without_ridges(px_per_mm, period_mm, ridge_mm, searched):
    """From an unknown scale (searched over every resolvable scale, or 10-120 px/mm), a square grating's period
    gives px/mm within 0.1 %, also where a pad's ridges outshine it; check_scale, told a scale 8 % off, finds the same."""
    lines = [square_line(period_mm, px_per_mm, ridge_mm=ridge_mm, phase=p, noise=0.05, seed=i)
             for i, p in enumerate((0.1, 1.7, 2.9))]
    measured = calibrate_scale(lines, period_mm, px_per_mm_range=searched, ridge_period_mm=ridge_mm)
    assert measured.n_measured == 3 and measured.px_per_mm == pytest.approx(px_per_mm, rel=1e-3)
    checked = check_scale(lines, period_mm, 1.08 * px_per_mm)
    assert checked.px_per_mm == pytest.approx(px_per_mm, rel=1e-3)
    if ridge_mm is not None:
        ridges = check_scale(lines, ridge_mm, 0.93 * px_per_mm)
        assert ridges.px_per_mm == pytest.approx(px_per_mm, rel=1e-3)


def test_a_flat_line_has_no_peak_and_the_check_says_it_is_unchecked():
    flat = np.full(LINE_PX, 0.5)
    assert np.isnan(strongest_peak(flat, 0.01, 0.05)[0])
    check = check_study_lines([("the pad's 1 mm ridges", 1.0, [flat] * 5)], 34.9)
    assert not check.checked and not check.off and check.summary().startswith("scale could not be confirmed: no scale")


@pytest.mark.parametrize("off", [0.95, 0.97, 1.0, 1.03, 1.10])
def test_the_scale_check_flags_beyond_its_tolerance(off):
    """Images at 34.9 px/mm read as if at 34.9 * off: the check measures 34.9 and says off exactly when the stated
    scale is more than the tolerance away."""
    lines = [square_line(1.0, 34.9, phase=p, noise=0.05, seed=i) for i, p in enumerate(np.linspace(0, 3, 6))]
    check = check_study_lines([("the pad's 1 mm ridges", 1.0, lines)], 34.9 * off)
    assert check.checked and check.measured_px_per_mm == pytest.approx(34.9, rel=1e-3)
    assert check.off == (abs(1 / off - 1) > SCALE_TOLERANCE)
    if check.off:
        assert check.reason().startswith("scale: the images measure 34.9")


def test_presses_of_one_mount_are_one_measurement_of_its_magnification():
    """Four mounts magnified 0.98, 1.0, 1.01, 1.03 (three presses each): the standard error is over the mounts
    (SD / 2), not over the twelve presses, and the median is the presses'."""
    magnification = [0.98, 1.0, 1.01, 1.03]
    lines, mounts = [], []
    for mount, m in enumerate(magnification):
        for press in range(3):
            lines.append(square_line(1.0, 34.9 * m, phase=press, noise=0.02, seed=10 * mount + press))
            mounts.append(mount)
    check = check_study_lines([("the pad's 1 mm ridges", 1.0, lines, mounts)], 34.9)
    measurement = check.measurement
    assert measurement.n_measured == 12 and measurement.n_mounts == 4
    assert measurement.standard_error == pytest.approx(np.std(magnification, ddof=1) / 2 / np.median(magnification),
                                                       rel=0.02)
    from scipy.stats import t

    assert check.limit == pytest.approx(max(SCALE_TOLERANCE, t.ppf(0.995, 3) * measurement.standard_error))


@pytest.mark.parametrize(("period_mm", "verdict"), [
    (0.3, "finer than the sensor resolves: period 0.30 mm, below the band's 1 mm (1/f_max)"),
    (0.5, "finer than the sensor resolves: period 0.50 mm, below the band's 1 mm (1/f_max)"),
    (0.8, "finer than the sensor resolves: period 0.80 mm, below the band's 1 mm (1/f_max)"),
    (2.0, ""), (3.0, ""), (5.0, ""),
    (10.0, "coarser than the sensor resolves: period 10"),
    (14.0, "coarser than the sensor resolves: period 14 mm, above the band's 10 mm (1/f_min)"),
])
@pytest.mark.parametrize("ridge_mm", [None, 1.0])
def test_the_band_test_names_the_period_of_the_whole_line(period_mm, verdict, ridge_mm):
    """A square grating's fundamental is 3x its 3rd harmonic: outside the band it dominates whatever the band holds,
    inside it is the band's own peak. The period named is the line's (the pad's ridges left out)."""
    line = square_line(period_mm, 34.9, ridge_mm=ridge_mm)
    reading = band_reading(line, 34.9, 0.1, 1.0, ridge_period_mm=ridge_mm)
    reason = band_reason(reading, 0.1, 1.0)
    assert reason.startswith(verdict) and bool(reason) == bool(verdict)
    if verdict:
        assert reading.period_mm == pytest.approx(period_mm, rel=0.03) and reading.dominance >= DOMINANCE


def test_a_surface_and_its_presses_never_disagree_unexplained():
    fine, inside = BandReading(0.5, 20.0), BandReading(0.5, 0.3)
    readings = [fine, fine, inside, inside, inside, fine, inside]
    surfaces = ["fine", "fine", "fine", "R3", "R3", "R3", "R3"]
    alone = band_reasons(readings, 0.1, 1.0)
    assert [bool(r) for r in alone] == [True, True, False, False, False, True, False]
    grouped = band_reasons(readings, 0.1, 1.0, surfaces)  # each press takes its surface's verdict
    assert all(r.startswith("surface (median of 3 presses) finer than the sensor resolves") for r in grouped[:3])
    assert grouped[3:] == ["", "", "", ""]


def test_calibrate_writes_the_measured_scale_into_study_toml(run_cli, tmp_path):
    """The tiny study's R3 presses are drawn at 20 px/mm: calibrate measures it from a stated 17, keeps the file's
    other lines, refuses to replace the user's value without --force, and --dry-run writes nothing."""
    from tests.analysis.test_dataset import make_study

    root = make_study(tmp_path / "tiny", repetitions=2)
    toml = root / "study.toml"
    text = toml.read_text().replace("px_per_mm = 20.0", "px_per_mm = 17.0  # my guess")
    toml.write_text("# my rig\n" + text)
    code, out, err = run_cli("calibrate", root, "--dry-run")
    assert code == 0, err
    assert "px/mm measured from 6 of 6 presses of R3 (3 mm) on the fingerprint pad" in out
    assert float(out.split()[0]) == pytest.approx(20.0, rel=2e-3) and "17.0" in toml.read_text()
    code, _, err = run_cli("calibrate", root)
    assert code == 2 and "px_per_mm is already 17.0 (yours); pass --force" in err and len(err.splitlines()) == 1
    code, out, err = run_cli("calibrate", root, "--force")
    assert code == 0, err
    import tomllib

    written = tomllib.loads(toml.read_text())
    assert written["sensor"]["px_per_mm"] == pytest.approx(20.0, rel=2e-3) and toml.read_text().startswith("# my rig")
    assert written["sensor"]["roi"] == [0, 16, 600, 32] and "(was 17)" in out
    code, _, err = run_cli("calibrate", root, "--specimen", "X9")
    assert code == 2 and "--specimen 'X9' is not in specimens.csv" in err


def test_predict_flags_every_row_when_the_study_scale_is_wrong(run_cli, tmp_path):
    """A study whose study.toml states 10 % too many px/mm: predict --study reads it at that scale (and says so),
    its gratings of stated period measure the true one, and every row is flagged 'scale' with one warning line."""
    from tests.analysis.test_dataset import make_study

    root = make_study(tmp_path / "tiny", repetitions=3)
    model = tmp_path / "m.json"
    assert run_cli("fit", "--study", root, "--pad", "fingerprint", "--condition", "2N", "--out", model)[0] == 0
    pred = tmp_path / "p.csv"
    code, _, err = run_cli("predict", model, "--study", root, "--out", pred)
    assert code == 0 and "against the stated 20 px/mm (+0.0 %" in err, err
    right = pd.read_csv(pred)
    toml = root / "study.toml"
    toml.write_text(toml.read_text().replace("px_per_mm = 20.0", "px_per_mm = 22.0"))
    code, _, err = run_cli("predict", model, "--study", root, "--out", pred, "--force")
    assert code == 0, err
    assert "images read at 22 px/mm, the scale in" in err
    warned = [line for line in err.splitlines() if "warning: scale: measured" in line]
    assert len(warned) == 1 and "against the stated 22 px/mm (-9.1 %" in warned[0]
    wrong = pd.read_csv(pred)
    assert set(wrong["px_per_mm"]) == {22.0} and wrong["extrapolates"].all()
    assert all(re.search(r"scale: the images measure 20(\.0\d)? px/mm, read at 22 px/mm", r) for r in wrong["outside"])
    assert not right["extrapolates"].any()


def test_fit_and_predict_warnings_reach_stderr_at_the_default_jobs(tmp_path):
    """Decoding in threads never changes the process's warning filters: at the default --jobs (every core) the
    controls line of fit and predict and predict's --roi auto field-of-view warning reach stderr."""
    from tests.analysis.test_dataset import make_study
    from tests.model.test_gate_file import ungated

    root = make_study(tmp_path / "tiny", repetitions=2)
    model = tmp_path / "m.json"

    def run(*args):
        done = subprocess.run([sys.executable, "-m", "roughsense.cli", *map(str, args)], capture_output=True, text=True,
                              timeout=600)
        assert done.returncode == 0, done.stderr
        return done.stderr

    err = run("fit", "--study", root, "--pad", "fingerprint", "--condition", "2N", "--model", "pls", "--out", model)
    failure = json.loads(model.read_text())["training"]["unseen"]["failure"]
    assert failure and f"roughsense: warning: {failure}" in err.splitlines()
    ungated(model)  # read at another scale: the gate (test_press_gate.py) may withhold some, exit status 3
    images = sorted((root / "images").glob("fingerprint_*_2N_*.png"))
    err = run("predict", model, "--roi", "auto", "--px-per-mm", "30", *images)
    assert f"roughsense: warning: {failure}" in err.splitlines()
    assert any("warning: --roi auto reads" in line for line in err.splitlines()), err


@pytest.mark.parametrize(("line", "problem"), [
    ("px_per_mmm = 8.725", "[sensor] unknown key 'px_per_mmm' looks like a misspelt 'px_per_mm', which is not set"),
    ("PX_per_mm = 8.725", "[sensor] unknown key 'PX_per_mm' looks like a misspelt 'px_per_mm'"),
    ("", "[sensor] states no px_per_mm: the paper's 34.9 px/mm is assumed"),
    ('px_per_mm = "8.7"', "[sensor] px_per_mm must be a positive number, got '8.7'"),
    ("px_per_mm = 0.5", "[sensor] px_per_mm 0.5 cannot resolve the band: its Nyquist frequency 0.25 mm^-1"),
    ("px_per_mm = 300.0", "[sensor] px_per_mm 300 makes the line 2 mm long (600 px), shorter than 1/f_min = 10 mm"),
    ("[sensors]", "unknown table 'sensors' looks like a misspelt [sensor], which is not there"),
])
def test_check_reports_a_missing_misspelt_or_implausible_scale(run_cli, tmp_path, line, problem):
    from tests.analysis.test_dataset import make_study

    root = make_study(tmp_path / "tiny", repetitions=1)
    toml = root / "study.toml"
    old = "[sensor]" if line == "[sensors]" else "px_per_mm = 20.0"
    toml.write_text(toml.read_text().replace(old, line))
    code, out, err = run_cli("check", root)
    assert code == 2 and problem in out, out
    if "misspelt" in problem:  # study refuses it too: never the default in its place
        code, _, err = run_cli("study", "--study", root, "--out", tmp_path / "report", "--permutations", "0")
        assert code == 2 and "looks like a misspelt" in err and len(err.splitlines()) == 1


def test_fit_reads_a_wrongly_stated_study_at_its_measured_scale_and_says_so(run_cli, tmp_path):
    """study.toml states 22 px/mm for images at 20: fit measures 20 on the gratings of stated period, fits at it (the model
    file's feature definition), records the check and prints one warning; at the right scale, one note."""
    from tests.analysis.test_dataset import make_study

    root = make_study(tmp_path / "tiny", repetitions=3)
    right, wrong = tmp_path / "right.json", tmp_path / "wrong.json"
    code, _, err = run_cli("fit", "--study", root, "--pad", "fingerprint", "--condition", "2N", "--out", right)
    assert code == 0 and "roughsense: scale: measured 20 px/mm" in err and "warning: scale" not in err, err
    toml = root / "study.toml"
    toml.write_text(toml.read_text().replace("px_per_mm = 20.0", "px_per_mm = 22.0"))
    code, _, err = run_cli("fit", "--study", root, "--pad", "fingerprint", "--condition", "2N", "--out", wrong)
    assert code == 0, err
    [line] = [line for line in err.splitlines() if "scale" in line]
    assert line.startswith("roughsense: warning: scale: measured 20") and "spectra read at the measured 20" in line
    fitted = json.loads(wrong.read_text())
    assert fitted["features"]["spectrum"]["px_per_mm"] == pytest.approx(20.0, rel=1e-3)
    assert fitted["training"]["scale_check"] == line.removeprefix("roughsense: warning: ")
    same = json.loads(right.read_text())["model"]  # the law fitted at the true scale, to the measurement's precision
    np.testing.assert_allclose(same["coefficients"], fitted["model"]["coefficients"], rtol=2e-2, atol=2e-3)


def test_a_weaker_outside_structure_is_named_only_where_a_family_flags_the_press():
    """Dominance 1.2: no band flag of its own (below 1.5), but the cause named where a family already flags it."""
    from roughsense.sensor.band import NAMING_DOMINANCE

    reading = BandReading(0.31, 1.2)
    assert band_reason(reading, 0.1, 1.0) == ""
    named = band_reason(reading, 0.1, 1.0, dominance=NAMING_DOMINANCE)
    assert named.startswith("finer than the sensor resolves: period 0.31 mm, below the band's 1 mm (1/f_max)")


@pytest.mark.parametrize(("passes", "model"), [((False, False, False, False), None), ((False, True, False, False), "pls"),
                                               ((True, False, False, True), "peak-law")])
def test_console_and_report_give_one_verdict_on_which_model_to_use(passes, model):
    """The console's "Which model to use" line and the report's first screen state the same family, or both none."""
    from roughsense.report.answer import NO_MODEL, _use_line, recommended_model, which_model_line

    unseen = pd.DataFrame({"model": ["peak-law", "pls", "peak-law", "pls"], "pad": ["smooth", "smooth", "fp", "fp"],
                           "condition": "combined", "rmse": 0.2, "null_rmse": 0.3, "pi90_coverage_trials": np.nan,
                           "passes": list(passes)})
    assert recommended_model(unseen) == model
    console, report = which_model_line(unseen), _use_line(unseen, unseen["passes"], "combined")
    if model is None:
        assert report == NO_MODEL and console.startswith(f"Which model to use: none. {NO_MODEL}")
    else:
        assert console.startswith(f"Which model to use: {model} (") and f"({model}, " in report


def test_one_mount_read_from_two_structures_is_one_mount():
    lines = [square_line(3.0, 34.9 * m, ridge_mm=1.0, phase=i, seed=i) for i, m in enumerate((0.99, 1.0, 1.01))]
    check = check_study_lines([("ridges", 1.0, lines, ["a", "b", "c"]), ("R3", 3.0, lines, ["a", "b", "c"])], 34.9)
    assert check.measurement.n_measured == 6 and check.measurement.n_mounts == 3


def test_the_default_search_spans_every_scale_the_target_resolves():
    """3 px per period (past Nyquist's 2) up to 5 periods on the line: a 480 px line and a 3 mm target search
    1-32 px/mm, so a downscaled camera at 8.7 px/mm (the example study's) is inside, unlike a fixed 10-120."""
    from roughsense.sensor.period import resolvable_scales

    assert resolvable_scales(480, 3.0) == pytest.approx((1.0, 32.0))
    lines = [square_line(3.0, 8.725, ridge_mm=1.0, phase=p, noise=0.05, seed=i)[:480] for i, p in enumerate((0.3, 2.2))]
    assert calibrate_scale(lines, 3.0, ridge_period_mm=1.0).px_per_mm == pytest.approx(8.725, rel=2e-3)


def test_calibrate_from_one_mount_states_no_precision_and_writes_nothing(run_cli, tmp_path):
    """One mount of R3 gives a value but no standard error: it is printed as unknown (never 'nan %') and study.toml
    is left as it was."""
    from tests.analysis.test_dataset import make_study

    root = make_study(tmp_path / "one", repetitions=1)
    before = (root / "study.toml").read_bytes()
    code, out, err = run_cli("calibrate", root, "--dry-run")
    assert code == 0 and "precision unknown from 1 mount" in out and "nan" not in out, err
    code, _, err = run_cli("calibrate", root, "--force")
    assert code == 2 and "1 mount(s) of the target cannot say how precise" in err and len(err.splitlines()) == 1
    assert (root / "study.toml").read_bytes() == before


def test_calibrate_without_the_reference_names_the_default_target_not_a_flag_never_given():
    """A study whose specimens.csv lacks the reference (a simulated study of other gratings): the error said
    "--specimen 'R3' is not in specimens.csv" though no --specimen was given; it now says what to pass."""
    from types import SimpleNamespace

    import pandas as pd

    from roughsense.cli.calibrate import _targets
    from roughsense.errors import ConfigError

    study = SimpleNamespace(manifest=pd.DataFrame(columns=["specimen", "pad", "repetition"]), reference_specimen="R3",
                            specimens=pd.DataFrame({"specimen": ["rect_10"], "wavelength_mm": [10.0]}),
                            pad_ridge_period_mm={})
    with pytest.raises(ConfigError) as raised:
        _targets(study, None, False, 30)
    assert raised.value.message == ("the reference specimen 'R3' (calibrate's default target) is not in specimens.csv; "
                                    "pass --specimen NAME (a specimen of known period) or --ridges")
    with pytest.raises(ConfigError) as raised:
        _targets(study, "X9", False, 30)
    assert raised.value.message == "--specimen 'X9' is not in specimens.csv"
