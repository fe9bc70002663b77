"""io/writer.py: a study folder written is read back as written, and a folder holding anything else is not written."""
from __future__ import annotations

import pytest

from roughsense.errors import OutputExistsError
from roughsense.io.sensor_settings import SensorSettings
from roughsense.io.study import read_study
from roughsense.io.writer import StudyWriter
from tests.studies import write_minimal_study


def test_study_round_trip(tmp_path):
    write_minimal_study(tmp_path / "s")
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
