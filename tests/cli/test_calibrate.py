"""``roughsense calibrate`` measures or refuses: presses with no clear peak, a scale the study reader would refuse, an
aperiodic target, a press counted twice, a folder another run is writing; study.toml keeps its mode and its BOM.

Each was a defect on 390ce82: noise presses gave 3.31 px/mm "+-6.4 %", --range 1,2 gave 1.60, a random surface 66
px/mm, a hard link halved the standard error, a 0600 study.toml became 0644 and a BOM was refused."""
from __future__ import annotations

import codecs
import os
import subprocess
import sys

import cv2
import numpy as np
import pandas as pd
import pytest

from tests.analysis.test_dataset import make_study


@pytest.fixture
def tiny(tmp_path):
    """The tiny study (gratings drawn at 20 px/mm, 600 px lines) stating 17 px/mm, three mounts of each specimen."""
    root = make_study(tmp_path / "tiny", repetitions=3)
    toml = root / "study.toml"
    toml.write_text(toml.read_text().replace("px_per_mm = 20.0", "px_per_mm = 17.0"))
    return root


def one_error(err: str) -> str:
    lines = [line for line in err.splitlines() if line.startswith("roughsense: error:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_presses_of_noise_are_refused_naming_them(tiny, run_cli):
    manifest = pd.read_csv(tiny / "manifest.csv")
    rng = np.random.default_rng(0)
    for image in manifest.loc[manifest["specimen"] == "R3", "image"]:
        cv2.imwrite(str(tiny / image), np.clip(128 + 40 * rng.standard_normal((64, 600)), 0, 255).astype(np.uint8))
    before = (tiny / "study.toml").read_bytes()
    code, out, err = run_cli("calibrate", tiny, "--force")
    assert code == 2 and out == ""
    line = one_error(err)
    assert "9 presses of 9 show no clear peak" in line and "images/fingerprint_R3_1N_1.png" in line
    assert (tiny / "study.toml").read_bytes() == before


@pytest.mark.parametrize("searched", ["1,2", "50,200"])
def test_a_range_that_holds_no_scale_of_the_target_is_refused(tiny, run_cli, searched):
    code, _, err = run_cli("calibrate", tiny, "--range", searched, "--dry-run")
    assert code == 2 and "nothing written" in one_error(err)


def test_a_scale_the_study_reader_refuses_is_never_written(tiny, run_cli, monkeypatch):
    """Whatever the presses say, a px_per_mm outside numbers.BOUNDS or one the band cannot be read at is refused."""
    from roughsense.cli import calibrate as command
    from roughsense.sensor.period import ScaleMeasurement

    for value, why in ((159348.0, "px_per_mm must be"), (1.6, "cannot resolve the band")):
        fake = ScaleMeasurement(3.0, np.full(9, value), np.arange(9).astype(str).astype(object))
        monkeypatch.setattr(command, "_measure", lambda *a, fake=fake: (fake, "R3"))
        code, _, err = run_cli("calibrate", tiny, "--force")
        assert code == 2 and why in one_error(err) and "17.0" in (tiny / "study.toml").read_text()


@pytest.mark.parametrize("shape", ["random", "other"])
def test_an_aperiodic_specimen_is_refused_as_a_target(tiny, run_cli, shape):
    specimens = pd.read_csv(tiny / "specimens.csv")
    specimens.loc[specimens["specimen"] == "R5", "shape"] = shape
    specimens.to_csv(tiny / "specimens.csv", index=False)
    code, _, err = run_cli("calibrate", tiny, "--specimen", "R5", "--dry-run")
    assert code == 2 and f"--specimen 'R5' is '{shape}' in specimens.csv, not a grating" in one_error(err)


def test_a_press_under_a_second_name_counts_once(tiny, run_cli):
    manifest = pd.read_csv(tiny / "manifest.csv")
    code, first, err = run_cli("calibrate", tiny, "--dry-run")
    assert code == 0, err
    copies = manifest[manifest["specimen"] == "R3"].copy()
    for row in copies.itertuples():
        os.link(tiny / row.image, tiny / row.image.replace(".png", "-again.png"))
    copies["image"] = copies["image"].str.replace(".png", "-again.png")
    copies["repetition"] += 3  # as if pressed in three more mounts
    pd.concat([manifest, copies]).to_csv(tiny / "manifest.csv", index=False)
    code, again, err = run_cli("calibrate", tiny, "--dry-run")
    assert code == 0, err
    assert again == first and "from 9 of 9 presses" in again


def test_the_folder_is_locked_while_it_is_measured(tiny, run_cli):
    """A run holding the folder (simulate --force swapping it, a capture) makes calibrate refuse at once, naming it."""
    holder = subprocess.Popen([sys.executable, "-c", (
        "import sys, time; from roughsense._util.lock import output_lock\n"
        "with output_lock(sys.argv[1], command='simulate'):\n"
        "    print('held', flush=True); time.sleep(60)"), str(tiny)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        code, _, err = run_cli("calibrate", tiny, "--force")
        assert code == 2 and "simulate" in one_error(err) and "17.0" in (tiny / "study.toml").read_text()
    finally:
        holder.kill()
        holder.wait()


def test_study_toml_keeps_its_mode_and_its_byte_order_mark(tiny, run_cli):
    toml = tiny / "study.toml"
    toml.write_bytes(codecs.BOM_UTF8 + toml.read_bytes())
    os.chmod(toml, 0o600)
    code, out, err = run_cli("check", tiny)  # read with its BOM: the one problem is the scale calibrate measures
    assert code == 2 and "against the stated 17 px/mm" in out, out
    code, out, err = run_cli("calibrate", tiny, "--force")
    assert code == 0 and "(was 17)" in out, err
    assert toml.stat().st_mode & 0o777 == 0o600
    raw = toml.read_bytes()
    assert raw.startswith(codecs.BOM_UTF8) and raw.count(codecs.BOM_UTF8) == 1
    import tomllib

    assert tomllib.loads(raw.decode("utf-8-sig"))["sensor"]["px_per_mm"] == pytest.approx(20.0, rel=3e-3)
    assert run_cli("check", tiny)[0] == 0


def test_a_range_where_only_a_harmonic_agrees_is_refused_and_the_true_scale_is_written(tmp_path, run_cli):
    """R3 pressed on the 1 mm-ridged pad only (a capture session): at 3x the scale the ridges' period falls on R3's,
    so --range 100,200 found "104.7 px/mm" on 390ce82. The target and the ridges agree only at 34.9."""
    from roughsense.sim.config import SimulationConfig, with_image_size
    from roughsense.sim.simulate import simulate_study

    config = SimulationConfig(pads=("fingerprint",), specimens=("R3",), repetitions=3, seed=11, participants=3,
                              sessions=2)
    root = simulate_study(tmp_path / "r3", with_image_size(config, 1920, 170), jobs=1)
    before = (root / "study.toml").read_bytes()
    code, _, err = run_cli("calibrate", root, "--range", "100,200", "--force")
    assert code == 2 and "nothing written" in one_error(err) and (root / "study.toml").read_bytes() == before
    code, out, err = run_cli("calibrate", root, "--force")
    assert code == 0, err
    import tomllib

    written = tomllib.loads((root / "study.toml").read_text())["sensor"]["px_per_mm"]
    assert written == pytest.approx(34.9, rel=0.03)


def test_a_scale_the_target_and_the_ridges_do_not_agree_on_is_refused():
    """A strong R3 under 1 mm ridges: every press shows a clear peak where the ridges would sit at 3x the scale (R3's
    own), yet R3 has none at 9 mm there: the search over every scale puts the agreement at the true one."""
    from roughsense.cli.calibrate import _refuse_disagreeing
    from roughsense.errors import ConfigError
    from tests.model.test_scale_check import grating_line

    lines = [grating_line(3.0, ridge_mm=1.0, grating=0.5, phase=k, seed=k) for k in range(6)]
    entries = [*(("R3", 3.0, line, str(k // 2)) for k, line in enumerate(lines)),
               *(("ridges", 1.0, line, str(k // 2)) for k, line in enumerate(lines))]
    _refuse_disagreeing(entries, 34.9, None)
    with pytest.raises(ConfigError, match=r"agree on 3[45](\.\d+)? px/mm, not on the 104.7 measured within --range 100,200"):
        _refuse_disagreeing(entries, 104.7, "100,200")
