"""explore/store.py: the Parquet store of a sweep's cells writes only into a results folder roughsense made."""
from __future__ import annotations

import pytest

from roughsense.errors import OutputExistsError
from tests.sweeps import big_sweep


def test_a_link_in_place_of_a_sweeps_results_folder_is_refused(tmp_path):
    """36.1 (the rule, explore): results/ as a link would send every cell's file into the folder it points to."""
    from roughsense.explore.store import ResultStore
    from roughsense.explore.sweep import read_sweep

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    out = tmp_path / "out"
    out.mkdir()
    (out / "results").symlink_to(elsewhere)
    with pytest.raises(OutputExistsError, match="results in it is not a folder roughsense made"):
        ResultStore(out, read_sweep(big_sweep(tmp_path, 1)), force=True)
    assert list(elsewhere.iterdir()) == []
