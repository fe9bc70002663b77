"""Issue 21, items 2 and 3: European Excel CSVs, hints for a unit or a name's case, and `roughsense check` listing
every problem of a study folder at once (while `study` keeps stopping at the first, with the same message)."""
from __future__ import annotations

import os
import warnings
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from roughsense.errors import InputError, RoughsenseWarning
from roughsense.io.ratings_file import read_ratings
from roughsense.io.study import read_study
from tests.as_user import as_nobody, needs_root
from tests.commands import check_output, error_line, manifest_lines, write_lines
from tests.fuzzing import EXAMPLES, FUZZ

SPECIMENS = [("R2", "rectangular", 2.0), ("R3", "rectangular", 3.0), ("R4", "rectangular", 4.0),
             ("S05", "sinusoidal", 0.5)]
FORCES = (1.02, 2.01)
RATINGS = [("P1", "1", "R2", 0.75), ("P1", "1", "R4", 1.25), ("P1", "1", "S05", 0.5),
           ("P2", "1", "R2", 0.8), ("P2", "1", "R4", 1.5), ("P2", "1", "S05", 0.25)]


def tables() -> dict[str, list[list[object]]]:
    """The three CSVs of a small study as rows (header first), numbers as numbers."""
    manifest = [["image", "specimen", "pad", "force_n", "repetition"]]
    for specimen, _, _ in SPECIMENS:
        for force in FORCES:
            manifest.append([f"images/{specimen}_{force:g}.png", specimen, "smooth", force, 1])
    return {
        "specimens.csv": [["specimen", "shape", "wavelength_mm"], *map(list, SPECIMENS)],
        "manifest.csv": manifest,
        "ratings.csv": [["participant", "session", "specimen", "rating"], *map(list, RATINGS)],
    }


def plain(rows) -> bytes:
    return "".join(",".join(str(c) for c in row) + "\n" for row in rows).encode()


def excel(rows) -> bytes:
    """What European Excel's "CSV (semicolon)" save writes: a BOM, ';' between cells, decimal commas, CRLF."""
    def cell(value):
        return f"{value:g}".replace(".", ",") if isinstance(value, float) else str(value)
    return "\ufeff".encode() + "".join(";".join(cell(c) for c in row) + "\r\n" for row in rows).encode()


def make_study(root: Path, *, write=plain) -> Path:
    (root / "images").mkdir(parents=True)
    (root / "study.toml").write_text('[study]\nname = "tiny"\nreference_specimen = "R3"\n\n'
                                     "[sensor]\npx_per_mm = 34.9\n\n[protocol]\nforces_n = [1.0, 2.0]\n")
    for name, rows in tables().items():
        (root / name).write_bytes(write(rows))
        if name == "manifest.csv":
            for row in rows[1:]:
                (root / row[0]).write_bytes(b"not decoded by check")
    return root


def tree(root: Path) -> dict[str, tuple[int, int]]:
    return {str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns) for p in root.rglob("*")}


# --------------------------------------------------------------------------- item 2: CSV dialects


def test_a_european_excel_study_reads_as_the_plain_one_with_one_warning_per_file(tmp_path):
    reference = read_study(make_study(tmp_path / "plain"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        euro = read_study(make_study(tmp_path / "euro", write=excel))
    assert sorted(euro.specimens["wavelength_mm"]) == [0.5, 2.0, 3.0, 4.0]
    assert list(euro.manifest["force_n"]) == [f for _ in SPECIMENS for f in FORCES]
    assert list(euro.ratings["rating"]) == [r[3] for r in RATINGS]
    for frame, ours in ((euro.specimens, reference.specimens), (euro.manifest, reference.manifest),
                        (euro.ratings, reference.ratings)):
        assert frame.equals(ours)
    messages = sorted(str(w.message) for w in caught if issubclass(w.category, RoughsenseWarning))
    assert messages == [f"{tmp_path / 'euro' / name}: read as semicolon-separated with decimal commas "
                        "(as European Excel saves it)" for name in ("manifest.csv", "ratings.csv", "specimens.csv")]


def test_semicolons_without_decimal_commas_say_only_that(tmp_path):
    path = tmp_path / "ratings.csv"
    path.write_text("participant;session;specimen;rating\nP1;1;R2;2\nP2;1;R2;3\n")
    with pytest.warns(RoughsenseWarning, match=r"read as semicolon-separated \(as European Excel saves it\)$"):
        frame = read_ratings(path)
    assert list(frame["rating"]) == [2.0, 3.0]


def test_decimal_commas_mixed_with_decimal_points_are_refused_with_the_fix(tmp_path):
    path = tmp_path / "ratings.csv"
    path.write_text("participant;session;specimen;rating\nP1;1;R2;0,5\nP2;1;R2;1.250\n")
    with pytest.raises(InputError) as caught:
        read_ratings(path)
    assert str(caught.value) == (f"{path}: is semicolon-separated but mixes decimal commas ('0,5', row 2) and "
                                 "decimal points ('1.250', row 3); write every number with the same decimal mark")


def test_a_header_mixing_semicolons_and_commas_says_how_to_save_it(tmp_path):
    path = tmp_path / "ratings.csv"
    path.write_text("participant;session;specimen,rating\nP1;1;R2,2\n")
    with pytest.raises(InputError, match=r"found participant;session;specimen, rating; the header mixes ',' and ';' "
                                         r"separators: use one throughout, e.g. save it as CSV UTF-8 \(comma delimited\)"):
        read_ratings(path)


def test_a_decimal_comma_in_a_comma_separated_file_gets_a_hint(tmp_path):
    path = tmp_path / "ratings.csv"
    path.write_text("participant,session,specimen,rating\nP1,1,R2,0,5\n")
    with pytest.raises(InputError) as caught:
        read_ratings(path)
    assert str(caught.value) == (f"{path}, row 2: 5 fields but the header has 4 (extra value '5'); a decimal comma? "
                                 "write numbers with a point (0.5, not 0,5)")
    path.write_text('participant,session,specimen,rating\nP1,1,R2,"0,5"\n')
    with pytest.raises(InputError, match=r"column 'rating': not a number: '0,5' \(a decimal comma: write 0.5\)$"):
        read_ratings(path)


# --------------------------------------------------------------------------- item 3: hints


@pytest.mark.parametrize("file, row, column, value, message", [
    ("manifest.csv", 3, "force_n", "2.01 N", "not a number: '2.01 N' (drop the unit: write 2.01)"),
    ("specimens.csv", 2, "wavelength_mm", "1.5mm", "not a number: '1.5mm' (drop the unit: write 1.5)"),
    ("manifest.csv", 4, "specimen", "r4", "unknown specimen 'r4' (not in specimens.csv; did you mean 'R4'?)"),
    ("ratings.csv", 3, "specimen", "r4", "unknown specimen 'r4' (not in specimens.csv; did you mean 'R4'?)"),
])
def test_a_unit_or_a_case_slip_gets_a_hint_in_the_same_line(tmp_path, file, row, column, value, message):
    root = make_study(tmp_path / "s")
    rows = tables()[file]
    rows[row - 1][rows[0].index(column)] = value
    (root / file).write_bytes(plain(rows))
    with pytest.raises(InputError) as caught:
        read_study(root)
    assert str(caught.value) == f"{root / file}, row {row}, column '{column}': {message}"


def test_a_pad_table_differing_only_by_case_from_a_manifest_pad_is_named(tmp_path):
    root = make_study(tmp_path / "s")
    with (root / "study.toml").open("a") as handle:
        handle.write("\n[pads.Smooth]\nridge_period_mm = 0.5\n")
    with pytest.warns(RoughsenseWarning, match=r"\[pads.Smooth\] names no pad of manifest.csv; did you mean "
                                               r"'smooth'\? its ridge_period_mm is ignored"):
        read_study(root)


# --------------------------------------------------------------------------- item 3: roughsense check


def five_problems(root: Path) -> None:
    """Five problems in three files: what `study` would report one run at a time."""
    files = tables()
    files["manifest.csv"][2][3] = "2.01 N"       # row 3: a unit
    files["manifest.csv"][4][1] = "r4"           # row 5: a case slip
    files["specimens.csv"][2][2] = "-3"          # row 3: a non-positive wavelength
    files["ratings.csv"][4][3] = "lots"          # row 5: not a number
    for name, rows in files.items():
        (root / name).write_bytes(plain(rows))
    (root / files["manifest.csv"][8][0]).unlink()  # row 9: an image file missing


def test_check_lists_every_problem_exits_2_and_writes_nothing(tmp_path, run_cli):
    root = make_study(tmp_path / "s")
    five_problems(root)
    before = tree(tmp_path)
    code, out, err = run_cli("check", root)
    assert code == 2
    assert out.splitlines() == [
        f"{root / 'specimens.csv'}, row 3, column 'wavelength_mm': must be positive, got -3",
        f"{root / 'manifest.csv'}, row 3, column 'force_n': not a number: '2.01 N' (drop the unit: write 2.01)",
        f"{root / 'manifest.csv'}, row 5, column 'specimen': unknown specimen 'r4' (not in specimens.csv; "
        "did you mean 'R4'?)",
        f"{root / 'manifest.csv'}, row 9, column 'image': image file not found: images/S05_2.01.png",
        f"{root / 'ratings.csv'}, row 5, column 'rating': not a number: 'lots'",
    ]
    assert err.splitlines() == [f"roughsense: error: {root}: 5 problems (listed above); fix them and run "
                                f"`roughsense check {root}` again"]
    assert tree(tmp_path) == before


def test_study_still_stops_at_the_first_problem_with_the_same_message(tmp_path):
    root = make_study(tmp_path / "s")
    five_problems(root)
    with pytest.raises(InputError) as caught:
        read_study(root)
    assert str(caught.value) == f"{root / 'specimens.csv'}, row 3, column 'wavelength_mm': must be positive, got -3"


def test_check_of_a_good_folder_is_one_summary_line(tmp_path, run_cli):
    root = make_study(tmp_path / "s")
    code, out, err = run_cli("check", root)
    assert (code, out) == (0, "study OK: 8 images, 4 specimens, 6 ratings\n")
    # its images are bytes no decoder reads: check looks for them; the scale check, which reads some, says it could not
    [line] = err.splitlines()
    assert line.startswith("roughsense: scale could not be confirmed: ") and "images/R3_1.02.png" in line
    code, out, err = run_cli("check", make_study(tmp_path / "euro", write=excel))
    assert code == 0 and out == "study OK: 8 images, 4 specimens, 6 ratings\n"
    assert len(err.splitlines()) == 4 and all("read as semicolon-separated" in line for line in err.splitlines()[:3])


def test_check_lists_a_scale_the_images_measure_otherwise_as_a_problem(simulated_tiny, tmp_path, run_cli):
    """The twin's study at 34.9 px/mm stated as 28, and as 34.9: on 390ce82 check ran no scale check at all."""
    import shutil

    root = tmp_path / "s"
    shutil.copytree(simulated_tiny, root)
    code, out, err = run_cli("check", root)
    assert code == 0 and "roughsense: scale: measured 3" in err and "against the stated 34.9 px/mm" in err, err
    toml = root / "study.toml"
    toml.write_text(toml.read_text().replace("px_per_mm = 34.9", "px_per_mm = 28.0"))
    code, out, err = run_cli("check", root)
    [problem] = out.splitlines()
    assert code == 2 and problem.startswith(f"{toml}: [sensor] scale: measured 3")
    assert "against the stated 28 px/mm" in problem and f"roughsense calibrate {root}" in problem


def test_check_goes_on_past_a_broken_file_and_bounds_the_list(tmp_path, run_cli):
    root = make_study(tmp_path / "s")
    (root / "specimens.csv").write_text("specimen,shape\nR2,rectangular\n")
    rows = tables()["ratings.csv"][:1] + [[f"P{i}", "1", "R2", "x"] for i in range(250)]
    (root / "ratings.csv").write_bytes(plain(rows))
    code, out, err = run_cli("check", root)
    lines = out.splitlines()
    assert code == 2 and len(lines) == 201
    assert lines[0] == f"{root / 'specimens.csv'}: missing column(s) wavelength_mm; found specimen, shape"
    assert lines[1] == f"{root / 'ratings.csv'}, row 2, column 'rating': not a number: 'x'"
    assert lines[-1] == "... and 51 more"
    assert "251 problems" in err


def test_check_refuses_a_missing_folder_in_one_line(tmp_path, run_cli):
    code, out, err = run_cli("check", tmp_path / "nope")
    assert (code, out) == (2, "") and err == f"roughsense: error: {tmp_path / 'nope'}: study folder not found\n"


def test_check_names_a_fifo_in_the_manifest(run_cli, tmp_path):
    """36.6: a FIFO in a manifest was reported as "not found"."""
    from tests.analysis.test_dataset import make_study

    root = make_study(tmp_path / "study", pads=("smooth",), repetitions=1)
    first = sorted((root / "images").iterdir())[0]
    first.unlink()
    os.mkfifo(first)
    code, out, err = run_cli("check", root)
    assert code == 2 and f"image file is a FIFO (named pipe), not a regular image file; give the image file itself: " \
        f"images/{first.name}" in out + err


@needs_root
def test_check_refuses_an_image_the_user_cannot_read(shared):
    """Also seen: `check` said "study OK" for an image the user cannot read (chmod 000)."""
    import contextlib
    import io

    from roughsense.cli import main
    from tests.analysis.test_dataset import make_study

    root = make_study(shared / "study", pads=("smooth",), repetitions=1)
    for path in [root, *root.rglob("*")]:
        os.chmod(path, 0o755 if path.is_dir() else 0o644)
    first = sorted((root / "images").iterdir())[0]
    os.chmod(first, 0)

    def check_as_nobody() -> str:
        text = io.StringIO()
        with contextlib.redirect_stdout(text), contextlib.redirect_stderr(text):
            code = main(["check", str(root)])
        return f"{code}\n{text.getvalue()}"

    said = as_nobody(check_as_nobody)
    assert said.startswith("2\n") and f"image file cannot be read (permission denied): images/{first.name}" in said


def test_two_decimal_commas_are_two_problems_not_four_or_a_pandas_error(run_cli, tmp_path):
    """Also seen: a decimal-comma row was reported twice, the second time as a raw pandas "C error"; and "run
    `roughsense check` again" omitted the folder."""
    from tests.analysis.test_dataset import make_study

    root = make_study(tmp_path / "study", pads=("smooth",), repetitions=1)
    lines = (root / "manifest.csv").read_text().splitlines()
    lines[1] = lines[1].replace(".", ",", 1)  # force 1,0116...: one field too many
    lines[3] = lines[3].replace(".", ",", 1) + ",5"  # images/x,png and a trailing value: two too many
    (root / "manifest.csv").write_text("\n".join(lines) + "\n")
    code, out, err = run_cli("check", root)
    listed = out.splitlines()
    assert code == 2 and len(listed) == 2, out
    assert listed[0].startswith(f"{root / 'manifest.csv'}, row 2: 6 fields but the header has 5")
    assert listed[1].startswith(f"{root / 'manifest.csv'}, row 4: 7 fields but the header has 5")
    assert error_line(err).endswith(f"2 problems (listed above); fix them and run `roughsense check {root}` again")


def test_check_lists_every_row_of_the_wrong_width(run_cli, tiny_copy):
    lines = manifest_lines(tiny_copy)
    lines[1] += ","
    lines[3] = lines[3].rsplit(",", 1)[0]
    write_lines(tiny_copy / "manifest.csv", lines)
    code, out, err = run_cli("check", tiny_copy)
    assert code == 2
    text = out + err
    assert "row 2: 6 fields but the header has 5" in text and "row 4: 4 fields but the header has 5" in text


def test_check_lists_every_file_name_too_long(run_cli, tiny_copy):
    """28.16: `check` stopped at the first "File name too long" instead of listing every row."""
    lines = manifest_lines(tiny_copy)
    for k, letter in ((1, "x"), (3, "y")):
        fields = lines[k].split(",")
        fields[0] = f"images/{letter * 300}.png"
        lines[k] = ",".join(fields)
    write_lines(tiny_copy / "manifest.csv", lines)
    text = check_output(run_cli, tiny_copy)
    for row in (2, 4):
        assert f"manifest.csv, row {row}, column 'image': image file cannot be looked up (File name too long)" in text


@pytest.mark.slow
@settings(FUZZ, max_examples=max(100, EXAMPLES))
@given(header=st.integers(1, 4), rows=st.lists(st.lists(st.sampled_from(["1", "", "x"]), min_size=0, max_size=6).map(
    lambda r: ["1", *r]), min_size=1, max_size=5))
def test_check_lists_each_row_of_a_wrong_width_once_and_never_a_parser_error(tmp_path_factory, header, rows):
    """36, Also seen: collecting, every row of the wrong width is one problem (its cells are not reported again) and
    the rows after it are still read: no pandas "C error"."""
    from roughsense.io.csv_read import read_table
    from roughsense.io.problems import Problems

    path = tmp_path_factory.mktemp("widths36") / "t.csv"
    path.write_text("\n".join([",".join(f"c{i}" for i in range(header)), *(",".join(r) for r in rows)]) + "\n")
    problems = Problems()
    read_table(path, [f"c{i}" for i in range(header)], numeric=["c0"], problems=problems)
    messages = [one.message for one in problems.items]
    assert not any("readable CSV" in m for m in messages), messages
    wrong = [i + 2 for i, r in enumerate(rows) if len(r) != header]
    width_rows = [one.row for one in problems.items if "fields but the header has" in one.message]
    assert width_rows == wrong
    assert len({one.row for one in problems.items if one.row in wrong}) == len(wrong)  # one problem per such row
    assert all(one.column is None for one in problems.items if one.row in wrong)
