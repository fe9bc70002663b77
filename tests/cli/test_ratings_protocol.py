"""``roughsense protocol`` and ``roughsense ratings`` end to end, including every bad-input path."""
from __future__ import annotations

import tracemalloc

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from tests.commands import HUGE, error_line, refusal_line


def fill(schedule_path, out_path, *, drop=None, seed=0):
    """Play the experimenter: type a rating into every row (optionally leave some blank)."""
    schedule = pd.read_csv(schedule_path, dtype={"participant": str, "session": str, "specimen": str})
    rng = np.random.default_rng(seed)
    wavelength = schedule.specimen.str[1:].astype(float)
    schedule["rating"] = np.round(wavelength / 3 * rng.lognormal(0, 0.2, len(schedule)), 3)
    if drop is not None:
        schedule.loc[drop(schedule), "rating"] = np.nan
    schedule.to_csv(out_path, index=False)
    return schedule


def test_protocol_then_ratings_round_trip(tmp_path, run_cli):
    schedule, sheet = tmp_path / "schedule.csv", tmp_path / "sheet.html"
    code, out, err = run_cli("protocol", "--participants", 4, "--sessions", 3, "--seed", 5,
                             "--out", schedule, "--sheet", sheet)
    assert code == 0, err
    assert "13 specimens" in out and "R3 excluded" in out and sheet.read_text().count("<section>") == 12
    filled = fill(schedule, tmp_path / "filled.csv")
    summary_path = tmp_path / "summary.csv"
    code, out, err = run_cli("ratings", tmp_path / "filled.csv", "--out", summary_path)
    assert code == 0, err
    assert err == ""
    summary = pd.read_csv(summary_path).set_index("specimen")
    assert list(summary.columns) == ["gmean", "sd", "n_participants", "n_sessions"]
    medians = filled.groupby(["specimen", "participant"])["rating"].median()
    for specimen in ("R2", "C5"):
        assert summary.loc[specimen, "gmean"] == pytest.approx(stats.gmean(medians.loc[specimen]), rel=1e-12)
        assert summary.loc[specimen, "sd"] == pytest.approx(np.std(medians.loc[specimen], ddof=1), rel=1e-12)
        assert summary.loc[specimen, "n_participants"] == 4 and summary.loc[specimen, "n_sessions"] == 3
    assert summary.loc["R3", "gmean"] == 1.0 and np.isnan(summary.loc["R3", "sd"])
    assert "sample standard deviation (ddof=1)" in out and "C4.5" in out


def test_protocol_is_reproducible_from_the_seed(tmp_path, run_cli):
    for name, seed in (("a", 1), ("b", 1), ("c", 2)):
        assert run_cli("protocol", "--seed", seed, "--out", tmp_path / f"{name}.csv",
                       "--sheet", tmp_path / f"{name}.md")[0] == 0
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    assert (tmp_path / "a.md").read_bytes() == (tmp_path / "b.md").read_bytes()
    assert (tmp_path / "a.csv").read_bytes() != (tmp_path / "c.csv").read_bytes()
    assert len(pd.read_csv(tmp_path / "a.csv")) == 10 * 3 * 13  # the paper's design by default


def test_protocol_takes_specimens_from_a_study_file_and_a_custom_reference(tmp_path, run_cli):
    specimens = tmp_path / "specimens.csv"
    specimens.write_text("specimen,shape,wavelength_mm\nS1,sinusoidal,1\nS2,sinusoidal,2\nS3,sinusoidal,3\n")
    code, _, err = run_cli("protocol", "--participants", 2, "--sessions", 1, "--specimens", specimens,
                           "--reference", "S2", "--seed", 0, "--out", tmp_path / "s.csv")
    assert code == 0, err
    assert sorted(set(pd.read_csv(tmp_path / "s.csv").specimen)) == ["S1", "S3"]


def test_missing_session_is_one_warning_line_and_the_summary_goes_on(tmp_path, run_cli):
    run_cli("protocol", "--participants", 3, "--sessions", 3, "--seed", 2, "--out", tmp_path / "s.csv")
    fill(tmp_path / "s.csv", tmp_path / "filled.csv", drop=lambda s: (s.participant == "P02") & (s.session == "3"))
    code, _, err = run_cli("ratings", tmp_path / "filled.csv", "--out", tmp_path / "summary.csv")
    assert code == 0
    lines = err.strip().splitlines()
    assert lines == [f"roughsense: warning: {tmp_path / 'filled.csv'}: participant P02 has no ratings in session 3; "
                     "medians use the other sessions"]
    assert (tmp_path / "summary.csv").exists()


GOOD = "participant,session,specimen,rating\nP1,1,R2,0.5\nP1,1,C2,1.5\nP2,1,R2,0.4\nP2,1,C2,1.1\n"


@pytest.mark.parametrize(
    "text, expected",
    [
        (GOOD + "P3,1,R2,0\n", "row 6, column 'rating': a magnitude estimate must be positive, got 0"),
        (GOOD + "P3,1,R2,lots\n", "row 6, column 'rating': not a number: 'lots'"),
        (GOOD + "P3,1,R3,1\n", "row 6, column 'specimen': R3 is the reference"),
        ("participant,session,rating\nP1,1,0.5\n", "missing column(s) specimen"),
        (GOOD + "P3,1,Q7,1\n", "row 6, column 'specimen': unknown specimen 'Q7'"),
    ],
)
def test_bad_ratings_are_one_line_exit_2_and_nothing_written(tmp_path, run_cli, text, expected):
    path = tmp_path / "ratings.csv"
    path.write_text(text)
    specimens = tmp_path / "specimens.csv"
    specimens.write_text("specimen,shape,wavelength_mm\nR2,rectangular,2\nR3,rectangular,3\nC2,circular,2\n")
    code, out, err = run_cli("ratings", path, "--specimens", specimens, "--out", tmp_path / "summary.csv")
    assert code == 2
    assert err.startswith(f"roughsense: error: {path}") and expected in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "summary.csv").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ratings.csv", "specimens.csv"]


def test_outputs_are_not_overwritten_without_force(tmp_path, run_cli):
    path = tmp_path / "ratings.csv"
    path.write_text(GOOD)
    out = tmp_path / "summary.csv"
    out.write_text("mine\n")
    code, _, err = run_cli("ratings", path, "--out", out)
    assert code == 2 and "--force" in err and out.read_text() == "mine\n"
    assert run_cli("ratings", path, "--out", out, "--force")[0] == 0
    assert out.read_text().startswith("specimen,gmean,sd,n_participants,n_sessions")
    sheet = tmp_path / "sheet.md"
    sheet.write_text("mine\n")
    code, _, err = run_cli("protocol", "--seed", 0, "--out", tmp_path / "s.csv", "--sheet", sheet)
    assert code == 2 and sheet.read_text() == "mine\n" and not (tmp_path / "s.csv").exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (("--sheet", "sheet.pdf"), "--sheet must end in .html or .md"),
        (("--specimens", "R2,R2"), "listed twice"),
        (("--specimens", "R3"), "besides the reference"),
        (("--participants", "0"), "--participants"),
    ],
)
def test_bad_protocol_options(tmp_path, run_cli, args, message):
    code, _, err = run_cli("protocol", "--seed", 0, "--out", tmp_path / "s.csv",
                           *[tmp_path / a if a.endswith(".pdf") else a for a in args])
    assert code == 2 and message in err
    assert list(tmp_path.iterdir()) == []


def test_help_explains_both_commands(run_cli):
    code, out, _ = run_cli("ratings", "--help")
    assert code == 0 and "geometric mean" in out and "median" in out
    code, out, _ = run_cli("protocol", "--help")
    assert code == 0 and "reference" in out and "--seed" in out


def test_extra_fields_through_the_cli(tmp_path, run_cli):
    """A value beyond the header is one error naming the line; a spreadsheet's trailing commas are harmless."""
    shifted = tmp_path / "shifted.csv"
    shifted.write_text("participant,session,specimen,rating\nP1,1,R2,0.5\nP2,1,R2,0.4,9\n")
    code, _, err = run_cli("ratings", shifted, "--out", tmp_path / "bad.csv")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert err.startswith(f"roughsense: error: {shifted}, row 3: 5 fields but the header has 4 (extra value '9')")
    assert not (tmp_path / "bad.csv").exists()

    plain, commas = tmp_path / "plain.csv", tmp_path / "commas.csv"
    plain.write_text(GOOD)
    commas.write_text("".join(line + ",\n" for line in GOOD.splitlines()))
    assert run_cli("ratings", plain, "--out", tmp_path / "plain_summary.csv")[0] == 0
    code, _, err = run_cli("ratings", commas, "--out", tmp_path / "commas_summary.csv")
    assert code == 0, err
    assert (tmp_path / "commas_summary.csv").read_bytes() == (tmp_path / "plain_summary.csv").read_bytes()
    summary = pd.read_csv(tmp_path / "commas_summary.csv").set_index("specimen")
    assert summary.loc["C2", "gmean"] == pytest.approx(np.sqrt(1.5 * 1.1), rel=1e-12)


def test_ratings_reads_european_excel_with_one_warning_and_hints_a_case_slip(tmp_path, run_cli):
    """Issue 21: ';' with decimal commas is read (one warning line); 'r2' for R2 is refused with a hint."""
    plain, euro = tmp_path / "plain.csv", tmp_path / "euro.csv"
    plain.write_text(GOOD)
    euro.write_bytes("\ufeff".encode() + GOOD.replace(",", ";").replace(".", ",").replace("\n", "\r\n").encode())
    assert run_cli("ratings", plain, "--out", tmp_path / "plain_summary.csv")[0] == 0
    code, _, err = run_cli("ratings", euro, "--out", tmp_path / "euro_summary.csv")
    assert code == 0
    assert err == (f"roughsense: warning: {euro}: read as semicolon-separated with decimal commas "
                   "(as European Excel saves it)\n")
    assert (tmp_path / "euro_summary.csv").read_bytes() == (tmp_path / "plain_summary.csv").read_bytes()

    slip = tmp_path / "slip.csv"
    slip.write_text(GOOD + "P3,1,r2,1.5\n")
    specimens = tmp_path / "specimens.csv"
    specimens.write_text("specimen,shape,wavelength_mm\nR2,rectangular,2\nR3,rectangular,3\nC2,circular,2\n")
    code, _, err = run_cli("ratings", slip, "--specimens", specimens, "--out", tmp_path / "s.csv")
    assert code == 2
    assert err == (f"roughsense: error: {slip}, row 6, column 'specimen': unknown specimen 'r2' "
                   "(expected one of C2, R2, R3; did you mean 'R2'?)\n")


def test_ratings_never_replaces_its_specimens_table(run_cli, tmp_path):
    """36.3: ``ratings --specimens FILE -o FILE --force`` replaced the specimens table with the summary."""
    specimens = tmp_path / "specimens.csv"
    specimens.write_text("specimen,shape,wavelength_mm\nR2,rectangular,2\nR3,rectangular,3\n")
    ratings = tmp_path / "ratings.csv"
    ratings.write_text("participant,session,specimen,rating\nP01,1,R2,0.5\nP02,1,R2,0.7\n")
    before = specimens.read_bytes()
    code, _, err = run_cli("ratings", ratings, "--specimens", specimens, "-o", specimens, "--force")
    assert code == 2 and "an input of this run" in error_line(err) and specimens.read_bytes() == before


def test_protocol_sheet_never_replaces_its_specimens_table(run_cli, tmp_path):
    """36.3 (the rule): protocol's --sheet is checked against --specimens too, not only --out."""
    specimens = tmp_path / "specimens.md"
    specimens.write_text("specimen,shape,wavelength_mm\nS1,sinusoidal,1\nS2,sinusoidal,2\nS3,sinusoidal,3\n")
    before = specimens.read_bytes()
    code, _, err = run_cli("protocol", "--seed", 0, "--specimens", specimens, "--reference", "S2",
                           "--out", tmp_path / "s.csv", "--sheet", specimens, "--force")
    assert code == 2 and "--sheet" in error_line(err) and specimens.read_bytes() == before


def test_a_huge_rating_cell_is_one_short_line_in_bounded_memory(run_cli, tmp_path):
    ratings = tmp_path / "ratings.csv"
    pd.DataFrame({"participant": ["P01", "P01"], "session": [1, 1], "specimen": ["R2", "R4"],
                  "rating": ["9" * HUGE + "x", "1.0"]}).to_csv(ratings, index=False)
    tracemalloc.start()
    try:
        code, _, err = run_cli("ratings", ratings, "--out", tmp_path / "agg.csv")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    line = refusal_line(code, err)
    assert line.startswith(f"roughsense: error: {ratings}, row 2, column 'rating': not a number: '999")
    assert len(err) < 1000
    assert peak < 40 * HUGE  # escaping a cell character by character took ~16 bytes a character on top of reading it


def test_a_huge_option_value_is_one_short_line(run_cli, tmp_path):
    code, _, err = run_cli("ratings", tmp_path / "r.csv", "--out", tmp_path / "o.csv", "--reference", "R" * 100_000)
    assert len(refusal_line(code, err)) < 600


def test_protocol_recommends_gratings_that_tell_period_from_groove_and_says_why(tmp_path, run_cli):
    """Issue 46: the paper's set ties groove width to period; protocol names the rectangles to print (the twin's
    paper+grooves: lands of 0.3 and 0.7 of the period), in the console and on the sheet, and why."""
    from roughsense.sim.specimens import GROOVE_SPECS

    code, out, err = run_cli("protocol", "--seed", 0, "--out", tmp_path / "s.csv", "--sheet", tmp_path / "s.md")
    assert code == 0, err
    assert f"Print these gratings too, to tell period from groove width: {', '.join(GROOVE_SPECS)}" in out
    assert "rect:2:1:0.6" in out and "rect:5:1:3.5" in out and "Lederman 1974" in out
    assert "Klatzky & Lederman 2007" in out and "half land, half groove" in out
    sheet = (tmp_path / "s.md").read_text()
    assert "rect:4:1:1.2" in sheet and "Why:" in sheet
    # The sheet still reads back (the advice is prose, not a table).
    fill(tmp_path / "s.csv", tmp_path / "filled.csv")
    assert run_cli("ratings", tmp_path / "filled.csv", "--out", tmp_path / "sum.csv")[0] == 0


def test_protocol_recommends_only_what_the_set_lacks(tmp_path, run_cli):
    # A set with two lands at one period already tells them apart: nothing to add.
    code, out, err = run_cli("protocol", "--seed", 0, "--out", tmp_path / "a.csv", "--specimens",
                             "R3,R2,R4,rect_4_1_1.2,C4")
    assert code == 0, err
    assert "Print these gratings" not in out
    # The twin's set names its gratings; a specimens.csv gives their lands in ridge_width_mm.
    code, out, err = run_cli("protocol", "--seed", 0, "--out", tmp_path / "b.csv", "--specimens", "paper+grooves")
    assert code == 0, err
    assert "21 specimens" in out and "Print these gratings" not in out
    assert "rect_2_1_0.6" in set(pd.read_csv(tmp_path / "b.csv").specimen)
    table = tmp_path / "specimens.csv"
    table.write_text("specimen,shape,wavelength_mm,ridge_width_mm\nR3,rectangular,3,1.5\nA,rectangular,2,0.6\n"
                     "B,rectangular,4,2\nC,circular,4,\n")
    code, out, err = run_cli("protocol", "--seed", 0, "--out", tmp_path / "c.csv", "--specimens", table,
                             "--participants", 2, "--sessions", 1)
    assert code == 0, err
    assert "rect:2:1:1.4, rect:3:1:0.9" in out and "rect:2:1:0.6" not in out
