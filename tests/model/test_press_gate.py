"""predict's gate on a small simulated study: each hostile class withheld (or flagged), withheld rows in the CSV with
their reason, the exit status, a batch going on past an unreadable image, and predictions the gate lets through
unchanged."""
from __future__ import annotations

import warnings

import cv2
import numpy as np
import pandas as pd
import pytest

from roughsense.cli import main


@pytest.fixture(scope="module")
def gated_model(simulated_tiny, tmp_path_factory):
    """The default model of the tiny study's smooth pad at 2N, with its contact-image gate."""
    out = tmp_path_factory.mktemp("gate") / "smooth.json"
    assert main(["fit", "--study", str(simulated_tiny), "--pad", "smooth", "--condition", "2N", "--out", str(out)]) == 0
    return out


def _presses(study) -> list:
    return sorted((study / "images").glob("smooth_*_2N_*.png"))


def _hostile(study, tmp_path) -> dict[str, np.ndarray]:
    press = cv2.imread(str(_presses(study)[0]), cv2.IMREAD_GRAYSCALE)
    h, w = press.shape
    rng = np.random.default_rng(0)
    frames = {"white noise": rng.integers(0, 256, (h, w)).astype(np.uint8),
              "blank": np.clip(100 + rng.normal(0, 2, (h, w)), 0, 255).astype(np.uint8),
              "background": np.clip(14 + rng.normal(0, 12, (h, w)), 0, 255).astype(np.uint8)}  # the twin's, no band
    page = np.full((h, w), 235, np.uint8)
    for row in range(4):
        cv2.putText(page, "The quick brown fox jumps over the lazy dog " * 3, (5, 30 + 38 * row),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.9, 20, 2)
    frames["typed page"] = page
    for name, angle, scale in (("rotated 15", 15, 1.0), ("magnified 15 %", 0, 1.15)):
        matrix = cv2.getRotationMatrix2D((w / 2, h / 2), angle, scale)
        frames[name] = cv2.warpAffine(press, matrix, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    import skimage.data as skimage  # a test dependency (pyproject), its photographs inside the wheel
    frames["photograph"] = cv2.resize(skimage.brick(), (w, h), interpolation=cv2.INTER_AREA)
    paths = {}
    for name, frame in frames.items():
        paths[name] = tmp_path / f"{name.replace(' ', '_').replace('%', 'pc')}.png"
        cv2.imwrite(str(paths[name]), frame)
    return paths


def test_each_hostile_class_is_withheld_or_flagged(gated_model, simulated_tiny, tmp_path):
    import roughsense as rs

    hostile = _hostile(simulated_tiny, tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = rs.predict(gated_model, [str(p) for p in hostile.values()])
    caught = table["withheld"] | table["extrapolates"]
    assert caught.all(), table.loc[~caught, "image"].tolist()
    assert table.loc[table["withheld"], "roughness_rel_R3"].isna().all()
    reasons = dict(zip(hostile, table["outside"]))
    assert "not a contact image like the training presses" in reasons["white noise"]
    assert "pixel noise" in reasons["magnified 15 %"] or "smoothed pixel noise" in reasons["magnified 15 %"]


def test_withheld_rows_in_the_csv_exit_status_3_and_the_batch_goes_on(gated_model, simulated_tiny, tmp_path, capsys):
    presses = [str(p) for p in _presses(simulated_tiny)[:2]]
    noise = tmp_path / "noise.png"
    cv2.imwrite(str(noise), np.random.default_rng(1).integers(0, 256, (170, 1920)).astype(np.uint8))
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"not an image")
    out = tmp_path / "pred.csv"
    code = main(["predict", str(gated_model), presses[0], str(noise), str(broken), presses[1], "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 3
    assert "roughsense: 2 of 4 rows withheld" in err and "exit status 3" in err
    table = pd.read_csv(out, keep_default_na=False)
    assert list(table["withheld"]) == [False, True, True, False]
    assert table["roughness_rel_R3"][1] == "" and table["roughness_rel_R3"][2] == ""
    assert table["outside"][2].startswith("unreadable: ") and "broken.png" in table["outside"][2]
    alone = tmp_path / "alone.csv"
    assert main(["predict", str(gated_model), *presses, "--out", str(alone)]) == 0
    kept = pd.read_csv(alone)  # the gate never changes a prediction it lets through
    assert [table["roughness_rel_R3"][0], table["roughness_rel_R3"][3]] == [str(v) for v in kept["roughness_rel_R3"]]


def test_a_batch_none_of_whose_images_can_be_read_is_one_error(gated_model, tmp_path, capsys):
    code = main(["predict", str(gated_model), str(tmp_path / "missing.png")])
    err = capsys.readouterr().err
    assert code == 2 and "missing.png" in err and len(err.strip().splitlines()) == 1


def test_a_surface_whose_presses_are_all_withheld_gets_no_surface_value(gated_model, simulated_tiny, tmp_path):
    import roughsense as rs

    noise = []
    for seed in range(2):
        noise.append(tmp_path / f"n{seed}.png")
        cv2.imwrite(str(noise[-1]), np.random.default_rng(seed).integers(0, 256, (170, 1920)).astype(np.uint8))
    with pytest.warns(rs.errors.RoughsenseWarning, match="2 of 2 rows withheld"):
        table = rs.predict(gated_model, [str(p) for p in noise], same_surface=True)
    assert table["withheld"].all() and table["surface_roughness_rel_R3"].isna().all()


def test_orientation_is_written_beside_each_prediction(gated_model, simulated_tiny):
    import roughsense as rs

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = rs.predict(gated_model, [str(p) for p in _presses(simulated_tiny)])
    assert (table["orientation_deg"].abs() < 6).all() and not table["withheld"].any()
    assert ((table["contact_p"] > 0) & (table["contact_p"] <= 1)).all()


def test_the_figures_docs_quote_are_the_codes():
    """docs/sensor.md and README quote alpha, the orientation tolerance and the exit status: each is the code's."""
    from pathlib import Path

    from roughsense.cli._common import WITHHELD_EXIT
    from roughsense.model.contact_gate import ALPHA, ORIENTATION_TOLERANCE_DEG

    repo = Path(__file__).resolve().parents[2]
    docs = " ".join((repo / "docs" / "sensor.md").read_text(encoding="utf-8").split())
    readme = " ".join((repo / "README.md").read_text(encoding="utf-8").split())
    assert f"alpha ({ALPHA:.0%}".replace("%", " %") in docs
    assert f"+-{ORIENTATION_TOLERANCE_DEG:g} degrees" in docs
    assert f"exits with status {WITHHELD_EXIT}" in docs and f"exits with status {WITHHELD_EXIT} when it withheld" in readme


def test_live_frames_the_gate_withholds_get_no_number(gated_model, simulated_tiny):
    """--live scores a frame as predict reads the image alone: a noise frame is withheld, a press is scored."""
    import math

    from roughsense.model.modelfile import load_model
    from roughsense.model.scoring import frame_scorer

    score = frame_scorer(load_model(gated_model))
    noise = np.random.default_rng(3).integers(0, 256, (170, 1920, 3)).astype(np.uint8)
    value, reason = score(noise)
    assert math.isnan(value) and reason.startswith("withheld: not a contact image")
    press = cv2.cvtColor(cv2.imread(str(_presses(simulated_tiny)[0])), cv2.COLOR_BGR2RGB)
    value, _ = score(press)
    assert math.isfinite(value)


def test_capture_with_a_model_names_each_press_its_gate_would_withhold(gated_model, simulated_tiny, tmp_path,
                                                                       run_cli, monkeypatch):
    """`capture --model`: each press is checked as it is taken; a frame of noise among real presses is named at once,
    kept in the study (it is what the camera saw), and the run ends with exit status 3."""
    import io

    frames = tmp_path / "frames"
    frames.mkdir()
    presses = [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in _presses(simulated_tiny)[:2]]
    noise = np.random.default_rng(1).integers(0, 256, presses[0].shape).astype(np.uint8)
    for i, frame in enumerate([presses[0], noise, presses[1]]):
        cv2.imwrite(str(frames / f"img_{i:04d}.png"), frame)
    monkeypatch.setattr("sys.stdin", io.StringIO("\n\n\n"))  # Enter: each force at its nominal value
    out = tmp_path / "study"
    code, _, err = run_cli("capture", "--source", str(frames / "img_%04d.png"), "--out", str(out), "--specimen", "R3",
                           "--pad", "smooth", "--forces-n", "2", "--repetitions", "3", "--px-per-mm", "34.9",
                           "--model", str(gated_model))
    named = [line for line in err.splitlines() if line.startswith("roughsense: images/")]
    assert code == 3, err
    assert len(named) == 1 and "not a contact image like the training presses" in named[0], err
    assert "1 press(es) are no contact image" in err and len(pd.read_csv(out / "manifest.csv")) == 3


def test_capture_refuses_a_model_without_a_gate_before_the_camera(gated_model, tmp_path, run_cli):
    from tests.model.test_gate_file import ungated

    model = tmp_path / "old.json"
    model.write_bytes(gated_model.read_bytes())
    code, _, err = run_cli("capture", "--source", str(tmp_path / "none_%04d.png"), "--out", str(tmp_path / "s"),
                           "--specimen", "R3", "--pad", "smooth", "--model", str(ungated(model)))
    assert code == 2 and "--model: this model file has no contact-image gate" in err and "old.json" in err
    assert not (tmp_path / "s").exists()
