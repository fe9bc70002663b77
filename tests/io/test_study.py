"""io/study.py: reading a study folder refuses what its tables do not agree on, naming the row."""
from __future__ import annotations

import pytest

from roughsense.errors import InputError
from roughsense.io.study import read_study
from tests.studies import write_minimal_study


def test_study_with_unknown_specimen_names_the_row(tmp_path):
    write_minimal_study(tmp_path / "s")
    manifest = tmp_path / "s" / "manifest.csv"
    manifest.write_text(manifest.read_text().replace("R3", "R9"))
    with pytest.raises(InputError) as info:
        read_study(tmp_path / "s")
    assert info.value.row == 3 and "R9" in str(info.value)
