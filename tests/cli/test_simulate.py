"""``roughsense simulate`` at the command line: a one-image study, and every bad input is one line, exit 2."""
from __future__ import annotations

from pathlib import Path

import pytest

from roughsense.io.study import read_study


def test_simulate_writes_a_readable_study(run_cli, tmp_path):
    out = tmp_path / "s"
    code, stdout, err = run_cli("simulate", "--out", out, "--pads", "fingerprint", "--specimens", "C3",
                                "--forces-n", "1", "--repetitions", "1", "--seed", "5", "--jobs", "1",
                                "--fingerprint-period-mm", "0.5")
    assert code == 0, err
    assert "wrote 1 image, 1 specimen" in stdout
    study = read_study(out)
    assert list(study.manifest["image"]) == ["images/fingerprint_C3_1N_r01.png"]
    assert study.extra["simulation"]["fingerprint_period_mm"] == 0.5
    import cv2
    # a sensor window of 320 rows centred on the 1080-row sensor, recorded with the simulation's settings
    assert cv2.imread(str(out / study.manifest["image"][0]), cv2.IMREAD_UNCHANGED).shape == (320, 1920)
    assert study.extra["simulation"]["camera_stored_height_px"] == 320 and study.sensor.roi == "center"
    whole = tmp_path / "w"
    code, _, err = run_cli("simulate", "--out", whole, "--pads", "smooth", "--specimens", "R3", "--forces-n", "2",
                           "--repetitions", "1", "--jobs", "1", "--stored-height-px", "0")
    assert code == 0, err
    assert cv2.imread(str(whole / read_study(whole).manifest["image"][0]), cv2.IMREAD_UNCHANGED).shape == (1080, 1920)


@pytest.mark.parametrize(("args", "message"), [
    (("--specimens", "R9"), "unknown specimen 'R9'"),
    (("--specimens", "rect:-3"), "positive"),
    (("--specimens", "sin:0:0.2"), "positive"),
    (("--pads", "velvet"), "unknown pad 'velvet'"),
    (("--forces-n", "1,0"), "--forces-n: '0' must be positive"),
    (("--forces-n", "1,x"), "not a number"),
    (("--repetitions", "0"), "--repetitions must be a whole number from 1 to 10000"),
    (("--fingerprint-period-mm", "-1"), "--fingerprint-period-mm must be a positive"),
    (("--fingerprint-period-mm", "-1", "--pads", "smooth"), "--fingerprint-period-mm must be a positive"),
    (("--fingerprint-period-mm", "0", "--pads", "smooth"), "--fingerprint-period-mm must be a positive"),
    (("--fingerprint-period-mm", "nan", "--pads", "smooth"), "--fingerprint-period-mm must be a positive"),
    (("--ridge-height-mm", "inf", "--pads", "smooth"), "--ridge-height-mm must be a positive"),
    (("--forces-n", "1,1.0000001"), "too close to tell apart"),
    (("--seed", "-1"), "--seed must be"),
    (("--jobs", "0"), "--jobs must be at least 1"),
    (("--ratings-from", "table"), "--ratings-from must be one of paper, physics, got 'table'"),
    (("--stored-height-px", "321"), "even number of rows"),
])
def test_bad_input_is_one_line_and_exit_2(run_cli, tmp_path, args, message):
    out = tmp_path / "s"
    code, _, err = run_cli("simulate", "--out", out, *args)
    assert code == 2
    assert err.startswith("roughsense: error:") and message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()  # nothing written


def test_ratings_from_physics_feels_every_specimen(run_cli, tmp_path):
    out = tmp_path / "s"
    code, _, err = run_cli("simulate", "--out", out, "--pads", "smooth", "--specimens", "R2,R3,sin:3:0.3",
                           "--forces-n", "1", "--repetitions", "1", "--jobs", "1", "--ratings-from", "physics")
    assert code == 0, err
    study = read_study(out)
    assert study.extra["simulation"]["ratings_from"] == "physics"
    assert dict(study.specimens.set_index("specimen")["ratings_source"]) == {
        "R2": "physics", "R3": "physics", "sin_3_0.3": "physics"}
    assert set(study.ratings["specimen"]) == {"R2", "sin_3_0.3"}


def _tree(root):
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


_SMALL = ("--pads", "smooth", "--specimens", "R2", "--forces-n", "2", "--repetitions", "1", "--jobs", "1")


def test_non_empty_folder_needs_force_and_keeps_user_files(run_cli, tmp_path):
    out = tmp_path / "s"
    out.mkdir()
    (out / "mine.csv").write_text("a,b\n1,2\n")
    code, _, err = run_cli("simulate", "--out", out, *_SMALL)
    assert code == 2 and "not empty" in err and "--force" in err
    assert [p.name for p in out.iterdir()] == ["mine.csv"]
    code, _, err = run_cli("simulate", "--out", out, *_SMALL, "--force")  # not a simulated study: still refused
    assert code == 2 and "not a simulated study" in err and len(err.strip().splitlines()) == 1
    assert [p.name for p in out.iterdir()] == ["mine.csv"]
    sim = tmp_path / "sim"
    assert run_cli("simulate", "--out", sim, *_SMALL, "--seed", "1")[0] == 0
    (sim / "mine.csv").write_text("a,b\n1,2\n")
    code, _, err = run_cli("simulate", "--out", sim, *_SMALL, "--force")  # an earlier simulation: replaced
    assert code == 0, err
    assert (sim / "mine.csv").read_text() == "a,b\n1,2\n"
    assert len(read_study(sim).manifest) == 1 and read_study(sim).extra["simulation"]["seed"] == 0


def test_force_leaves_a_rig_study_untouched(run_cli, tmp_path):
    import numpy as np
    import pandas as pd

    from roughsense.io.sensor_settings import SensorSettings
    from roughsense.io.writer import StudyWriter

    rig = StudyWriter(tmp_path / "rig")
    rig.write_config(name="bench", sensor=SensorSettings(px_per_mm=34.9))
    rig.write_specimens(pd.DataFrame({"specimen": ["R2"], "shape": ["rectangular"], "wavelength_mm": [2.0]}))
    image = rig.write_image("smooth_R2_2N_r01.png", np.full((300, 400), 7, dtype=np.uint8))
    rig.write_manifest(pd.DataFrame({"image": [image], "specimen": ["R2"], "pad": ["smooth"], "force_n": [2.0],
                                     "repetition": [1]}))
    rig.write_ratings(pd.DataFrame({"participant": ["P01"], "session": [1], "specimen": ["R2"], "rating": [0.4]}))
    before = _tree(rig.root)
    code, _, err = run_cli("simulate", "--out", rig.root, *_SMALL, "--force")
    assert code == 2
    assert err.startswith("roughsense: error:") and "not a simulated study" in err
    assert len(err.strip().splitlines()) == 1
    assert _tree(rig.root) == before


def test_close_forces_into_an_earlier_simulation_change_nothing(run_cli, tmp_path):
    sim = tmp_path / "sim"
    assert run_cli("simulate", "--out", sim, *_SMALL)[0] == 0
    before = _tree(sim)
    code, _, err = run_cli("simulate", "--out", sim, "--pads", "smooth", "--specimens", "R2", "--repetitions", "1",
                           "--forces-n", "1,1.0000001", "--force")
    assert code == 2 and "1.0000001" in err
    assert _tree(sim) == before


def test_help_documents_specimen_specs(run_cli, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    code, stdout, _ = run_cli("simulate", "--help")
    assert code == 0
    text = " ".join(stdout.replace("│", " ").split())
    for needle in ("rect:WAVELENGTH[:DEPTH[:RIDGE_WIDTH]]", "default: all cores", "sin:WAVELENGTH:AMPLITUDE",
                   "--fingerprint-period-mm", "840 images"):
        assert needle in text


# --------------------------------------------------------------------------- captured frames are never replaced (issue 22)


def _captured(run_cli, monkeypatch, out):
    """A study the rig captured: three real frames (a video stands in for the camera) with their force readings."""
    import io

    from tests.videos import write_video

    monkeypatch.setattr("sys.stdin", io.StringIO("\n" * 3))
    code, _, err = run_cli("capture", "--source", write_video(out.parent / "camera.avi"), "--out", out,
                           "--specimen", "R2", "--pad", "smooth", "--roi", "auto", "--repetitions", "1",
                           "--shape", "rectangular", "--wavelength-mm", "2")
    assert code == 0, err
    return out


def _mixed(run_cli, monkeypatch, tmp_path):
    """A simulation a rig has captured into, as an older roughsense allowed: its rows appended to the manifest."""
    import shutil

    import pandas as pd

    rig = _captured(run_cli, monkeypatch, tmp_path / "rig")
    sim = tmp_path / "sim"
    assert run_cli("simulate", "--out", sim, *_SMALL)[0] == 0
    rows = pd.read_csv(rig / "manifest.csv")
    for image in rows["image"]:
        shutil.copy(rig / image, sim / image)
    manifest = pd.concat([pd.read_csv(sim / "manifest.csv"), rows], ignore_index=True)
    manifest.to_csv(sim / "manifest.csv", index=False)
    return sim, list(rows["image"])


def test_simulate_force_never_deletes_captured_frames(run_cli, tmp_path, monkeypatch):
    from roughsense.sim.overwrite import simulation_owned

    sim, frames = _mixed(run_cli, monkeypatch, tmp_path)
    before = _tree(sim)
    for extra in ((), ("--force",)):
        code, _, err = run_cli("simulate", "--out", sim, *_SMALL, *extra)
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert err.startswith(f"roughsense: error: {sim}: holds frames captured by the rig (manifest.csv rows with a "
                              "timestamp); a simulation never replaces real frames, --force or not")
        assert _tree(sim) == before
    owned = simulation_owned(sim)  # and were it ever asked, the swap would carry the real frames over
    assert not any(owned(Path(image)) for image in frames)
    assert owned(Path("images/smooth_R2_2N_r01.png")) and owned(Path("manifest.csv"))


def test_no_writer_replaces_a_captured_study(run_cli, tmp_path, monkeypatch):
    """Siblings: simulate --force and example --force onto a folder of real frames (each would replace its tables)."""
    rig = _captured(run_cli, monkeypatch, tmp_path / "rig")
    before = _tree(rig)
    for args in (("simulate", "--out", rig, *_SMALL, "--force"), ("example", "my-study", "--out", rig, "--force")):
        code, _, err = run_cli(*args)
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert err.startswith(f"roughsense: error: {rig}: holds frames captured by the rig"), err
        assert _tree(rig) == before
