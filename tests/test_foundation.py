"""The foundation: one error family, atomic writes and the study-folder contract."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from roughsense._util import atomic
from roughsense.errors import ConfigError, InputError, OutputExistsError, RoughsenseError
from roughsense.io.csv_read import read_table
from roughsense.io.protocol import assign_nominal_forces
from roughsense.io.sensor_settings import SensorSettings, parse_roi
from roughsense.io.study import read_study
from roughsense.io.writer import StudyWriter


def test_error_names_file_row_and_column(tmp_path):
    err = InputError("not a number", path=tmp_path / "a.csv", row=3, column="rating")
    assert str(err) == f"{tmp_path / 'a.csv'}, row 3, column 'rating': not a number"
    assert isinstance(err, RoughsenseError)


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.csv"
    with pytest.raises(ZeroDivisionError):
        with atomic.atomic_open(target) as handle:
            handle.write("partial")
            1 / 0
    assert list(tmp_path.iterdir()) == []
    atomic.write_text(target, "whole\n")
    assert target.read_text() == "whole\n"


def test_check_can_write_refuses_existing_without_force(tmp_path):
    target = tmp_path / "model.json"
    target.write_text("{}")
    with pytest.raises(OutputExistsError):
        atomic.check_can_write(target)
    assert atomic.check_can_write(target, force=True) == target


def test_read_table_names_the_line_of_a_bad_value(tmp_path):
    path = tmp_path / "ratings.csv"
    path.write_text("participant,session,specimen,rating\nP1,1,R2,0.5\nP1,2,R2,abc\n")
    with pytest.raises(InputError) as info:
        read_table(path, ["participant", "session", "specimen", "rating"], positive=["rating"])
    assert info.value.row == 3 and info.value.column == "rating"


@pytest.mark.parametrize(
    "text, expected",
    [("center", "center"), ("auto", "auto"), ("10,20,300,40", (10, 20, 300, 40)), ([0, 0, 5, 5], (0, 0, 5, 5))],
)
def test_parse_roi(text, expected):
    assert parse_roi(text) == expected


@pytest.mark.parametrize("text", ["1,2,3", "a,b,c,d", "0,0,0,5", "-1,0,5,5", "1.5,0,5,5"])
def test_parse_roi_rejects(text):
    with pytest.raises(RoughsenseError):
        parse_roi(text)


def test_nominal_force_is_nearest_protocol_force():
    manifest = pd.DataFrame({"force_n": [0.93, 2.08, 3.2]})
    out = assign_nominal_forces(manifest, (1.0, 2.0, 3.0))
    assert list(out["condition"]) == ["1N", "2N", "3N"]
    with pytest.raises(InputError):
        assign_nominal_forces(pd.DataFrame({"force_n": [4.2]}), (1.0, 2.0, 3.0))


def _write_minimal_study(root):
    import numpy as np

    writer = StudyWriter(root)
    writer.write_config(name="t", sensor=SensorSettings(px_per_mm=20.0, roi=(0, 0, 64, 8)))
    writer.write_specimens(pd.DataFrame({"specimen": ["R2", "R3"], "shape": ["rectangular"] * 2, "wavelength_mm": [2.0, 3.0]}))
    rows = []
    for specimen in ("R2", "R3"):
        rel = writer.write_image(f"{specimen}.png", np.full((8, 64), 128, np.uint8))
        rows.append({"image": rel, "specimen": specimen, "pad": "smooth", "force_n": 1.02, "repetition": 1})
    writer.write_manifest(pd.DataFrame(rows))
    return writer


def test_study_round_trip(tmp_path):
    _write_minimal_study(tmp_path / "s")
    study = read_study(tmp_path / "s")
    assert study.sensor == SensorSettings(px_per_mm=20.0, roi=(0, 0, 64, 8))
    assert study.forces_n == (1.0, 2.0, 3.0)
    assert list(study.manifest["condition"]) == ["1N", "1N"]
    assert all(p.is_file() for p in study.image_paths)


def test_study_writer_refuses_non_empty_folder(tmp_path):
    root = tmp_path / "s"
    root.mkdir()
    (root / "notes.txt").write_text("mine")
    with pytest.raises(OutputExistsError):
        StudyWriter(root)
    StudyWriter(root, force=True)
    assert (root / "notes.txt").read_text() == "mine"


def test_every_refusal_to_overwrite_names_the_cli_option_and_the_python_keyword(tmp_path):
    """One wording, errors.PASS_FORCE: a Python caller is told ``force=True``, not only the CLI's ``--force``."""
    from roughsense import sim
    from roughsense.errors import PASS_FORCE
    from roughsense.io.study_config import write_px_per_mm

    assert PASS_FORCE == "pass --force (force=True in Python)"
    root = tmp_path / "s"
    root.mkdir()
    (root / "notes.txt").write_text("mine")
    (tmp_path / "f.json").write_text("{}")
    (tmp_path / "study.toml").write_text("[sensor]\npx_per_mm = 17.0\n")
    refusals = [lambda: StudyWriter(root), lambda: atomic.check_can_write(tmp_path / "f.json"),
                lambda: sim.simulate_study(root, sim.SimulationConfig(pads=("smooth",), specimens=("R3",))),
                lambda: write_px_per_mm(tmp_path / "study.toml", 20.0, note="measured")]
    for refuse in refusals:
        with pytest.raises((OutputExistsError, ConfigError)) as info:
            refuse()
        assert f"; {PASS_FORCE} to " in str(info.value)
    assert (root / "notes.txt").read_text() == "mine" and "17.0" in (tmp_path / "study.toml").read_text()


def test_study_with_unknown_specimen_names_the_row(tmp_path):
    _write_minimal_study(tmp_path / "s")
    manifest = tmp_path / "s" / "manifest.csv"
    manifest.write_text(manifest.read_text().replace("R3", "R9"))
    with pytest.raises(InputError) as info:
        read_study(tmp_path / "s")
    assert info.value.row == 3 and "R9" in str(info.value)


def test_cli_error_is_one_line_exit_2(run_cli, tmp_path):
    from roughsense.cli import app

    @app.command("_boom", hidden=True)
    def _boom() -> None:
        raise InputError("bad thing", path=tmp_path / "x.csv", row=2)

    code, out, err = run_cli("_boom")
    assert code == 2
    assert err.strip().count("\n") == 0 and "x.csv, row 2: bad thing" in err
    assert "Traceback" not in err


def test_atomic_files_get_the_usual_permissions(tmp_path):
    import os

    umask = os.umask(0o022)
    try:
        path = atomic.write_text(tmp_path / "shared.csv", "a\n")
    finally:
        os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o644


def test_manifest_with_trailing_commas_reads_as_without(tmp_path):
    _write_minimal_study(tmp_path / "s")
    plain = read_study(tmp_path / "s")
    for name in ("manifest.csv", "specimens.csv"):
        path = tmp_path / "s" / name
        path.write_text("".join(line + ",\n" for line in path.read_text().splitlines()))
    commas = read_study(tmp_path / "s")
    pd.testing.assert_frame_equal(commas.manifest, plain.manifest)
    pd.testing.assert_frame_equal(commas.specimens, plain.specimens)
    assert list(commas.manifest["image"]) == ["images/R2.png", "images/R3.png"]


def test_manifest_row_with_an_extra_value_names_its_line(tmp_path):
    _write_minimal_study(tmp_path / "s")
    manifest = tmp_path / "s" / "manifest.csv"
    lines = manifest.read_text().splitlines()
    lines[2] += ",smooth"  # one row too long: pandas would have shifted it under the header
    manifest.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as info:
        read_study(tmp_path / "s")
    assert info.value.path == manifest and info.value.row == 3
    assert info.value.message == "6 fields but the header has 5 (extra value 'smooth')"


def test_number_errors_quote_the_cell_not_numpy(tmp_path):
    path = tmp_path / "specimens.csv"
    path.write_text("specimen,shape,wavelength_mm\nR2,rectangular,2\nR3,rectangular,inf\n")
    with pytest.raises(InputError) as info:
        read_table(path, ["specimen", "shape", "wavelength_mm"], positive=["wavelength_mm"])
    assert info.value.message == "not a finite number: 'inf'" and info.value.row == 3
    with pytest.raises(ConfigError, match=r"px_per_mm must be a positive number, got inf$"):
        SensorSettings(px_per_mm=np.float64("inf"))
    with pytest.raises(ConfigError, match=r"got 0,0,-1,5$"):
        parse_roi([np.int64(0), np.int64(0), np.int64(-1), np.int64(5)])


def test_blank_lines_keep_line_numbers_honest(tmp_path):
    path = tmp_path / "ratings.csv"
    path.write_text("participant,session,specimen,rating\nP1,1,R2,0.5\n\nP1,2,R2,abc\n")
    with pytest.raises(InputError) as info:
        read_table(path, ["participant", "session", "specimen", "rating"], positive=["rating"])
    assert info.value.row == 3 and "blank line" in str(info.value)
    path.write_text("participant,session,specimen,rating\nP1,1,R2,0.5\nP1,2,R2,abc\n\n\n")
    with pytest.raises(InputError) as info:
        read_table(path, ["participant", "session", "specimen", "rating"], positive=["rating"])
    assert info.value.row == 3 and info.value.column == "rating"  # trailing blank lines are ignored
    path.write_text("participant,session,specimen,rating\nP1,1,R2,0.5\n\n")
    assert len(read_table(path, ["participant", "session", "specimen", "rating"], positive=["rating"])) == 1
