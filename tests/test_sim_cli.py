"""``roughsense simulate`` at the command line: a one-image study, and every bad input is one line, exit 2."""
from __future__ import annotations

import pytest

from roughsense.study import read_study


def test_simulate_writes_a_readable_study(run_cli, tmp_path):
    out = tmp_path / "s"
    code, stdout, err = run_cli("simulate", "--out", out, "--pads", "fingerprint", "--specimens", "C3",
                                "--forces", "1", "--repetitions", "1", "--seed", "5", "--jobs", "1",
                                "--fingerprint-period-mm", "0.5")
    assert code == 0, err
    assert "wrote 1 images" in stdout
    study = read_study(out)
    assert list(study.manifest["image"]) == ["images/fingerprint_C3_1N_r01.png"]
    assert study.extra["simulation"]["fingerprint_period_mm"] == 0.5
    import cv2
    assert cv2.imread(str(out / study.manifest["image"][0]), cv2.IMREAD_UNCHANGED).shape == (1080, 1920)


@pytest.mark.parametrize(("args", "message"), [
    (("--specimens", "R9"), "unknown specimen 'R9'"),
    (("--specimens", "rect:-3"), "positive"),
    (("--specimens", "sin:0:0.2"), "positive"),
    (("--pads", "velvet"), "unknown pad 'velvet'"),
    (("--forces", "1,0"), "--forces: '0' must be positive"),
    (("--forces", "1,x"), "not a number"),
    (("--repetitions", "0"), "--repetitions must be at least 1"),
    (("--fingerprint-period-mm", "-1"), "period must be a positive"),
    (("--jobs", "0"), "--jobs must be at least 1"),
])
def test_bad_input_is_one_line_and_exit_2(run_cli, tmp_path, args, message):
    out = tmp_path / "s"
    code, _, err = run_cli("simulate", "--out", out, *args)
    assert code == 2
    assert err.startswith("roughsense: error:") and message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()  # nothing written


def test_non_empty_folder_needs_force_and_keeps_user_files(run_cli, tmp_path):
    out = tmp_path / "s"
    out.mkdir()
    (out / "mine.csv").write_text("a,b\n1,2\n")
    args = ("simulate", "--out", out, "--pads", "smooth", "--specimens", "R2", "--forces", "2", "--repetitions", "1",
            "--jobs", "1")
    code, _, err = run_cli(*args)
    assert code == 2 and "not empty" in err and "--force" in err
    assert [p.name for p in out.iterdir()] == ["mine.csv"]
    code, _, err = run_cli(*args, "--force")
    assert code == 0, err
    assert (out / "mine.csv").read_text() == "a,b\n1,2\n"
    assert len(read_study(out).manifest) == 1


def test_help_documents_specimen_specs(run_cli, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    code, stdout, _ = run_cli("simulate", "--help")
    assert code == 0
    text = " ".join(stdout.replace("│", " ").split())
    for needle in ("rect:WAVELENGTH[:DEPTH[:RIDGE_WIDTH]]", "default: all cores", "sin:WAVELENGTH:AMPLITUDE",
                   "--fingerprint-period-mm", "840 images"):
        assert needle in text
