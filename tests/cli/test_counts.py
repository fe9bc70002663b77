"""Counts printed by the CLI agree with their nouns: "1 image, 1 specimen", never "1 specimens"."""
from __future__ import annotations

import pandas as pd

from roughsense._util.text import counted


def test_counted_agrees_in_number():
    assert [counted(n, "cell") for n in (0, 1, 2, 14)] == ["0 cells", "1 cell", "2 cells", "14 cells"]
    assert counted(1, "repetition", "repetitions") == "1 repetition" and counted(3, "axis", "axes") == "3 axes"


def test_simulate_one_image_says_so(run_cli, tmp_path):
    code, out, err = run_cli("simulate", "--out", tmp_path / "s", "--pads", "smooth", "--specimens", "R3", "--forces-n",
                             "2", "--repetitions", "1", "--stored-height-px", "40")
    assert code == 0, err
    assert len(pd.read_csv(tmp_path / "s" / "manifest.csv")) == 1
    assert f"wrote 1 image, 1 specimen and the panel's ratings to {tmp_path / 's'}" in out


def test_protocol_one_session_and_one_specimen(run_cli, tmp_path):
    out_csv = tmp_path / "schedule.csv"
    code, out, err = run_cli("protocol", "--out", out_csv, "--seed", "1", "--participants", "2", "--sessions", "1",
                             "--specimens", "R2,R3")
    assert code == 0, err
    schedule = pd.read_csv(out_csv)
    assert schedule["session"].nunique() == 1 and schedule["specimen"].nunique() == 1
    assert f"wrote {out_csv}: 2 participants x 1 session x 1 specimen (reference R3 excluded)" in out
