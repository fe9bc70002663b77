"""Issue 28, the third hardening pass: no header, cache key, decimal comma or spelling changes a number silently,
and every size is bounded before work. Each test names the item it covers."""
from __future__ import annotations

import shutil

import pytest

from roughsense.errors import InputError
from roughsense.io import csv_read
from roughsense.io.problems import Problems
from roughsense.io.study import load_study, read_study

from .test_dataset import make_study


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    return make_study(tmp_path_factory.mktemp("tiny") / "study", pads=("smooth",), repetitions=2)


@pytest.fixture()
def study(tiny, tmp_path):
    return shutil.copytree(tiny, tmp_path / "study")


def one_error(run_cli, *args) -> str:
    code, _, err = run_cli(*args)
    assert code == 2 and "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.startswith("roughsense: error: ")]
    assert len(lines) == 1, err
    return lines[0]


def check_output(run_cli, root) -> str:
    """What `roughsense check` prints of a folder it refuses (one line per problem)."""
    code, out, err = run_cli("check", root)
    assert code == 2 and "Traceback" not in err, err
    return out + err


def manifest_lines(root) -> list[str]:
    return (root / "manifest.csv").read_text().splitlines()


def write_lines(path, lines) -> None:
    path.write_text("\n".join(lines) + "\n")


# --------------------------------------------------------------------------- 3. field counts and leading zeros


def test_a_decimal_comma_before_a_blank_optional_column_is_refused(study):
    """28.3: ``2,0104,2`` under force_n,repetition,timestamp read as repetition 104 and `check` said OK."""
    lines = manifest_lines(study)
    header = lines[0].split(",")
    assert header[-2:] == ["force_n", "repetition"]
    lines[0] += ",timestamp"
    fields = lines[1].split(",")
    lines[1] = ",".join([*fields[:-2], "2,0104", fields[-1], ""])  # force 2,0104 (decimal comma), timestamp blank
    lines[2:] = [line + "," for line in lines[2:]]
    write_lines(study / "manifest.csv", lines)
    with pytest.raises(InputError, match=r"7 fields but the header has 6 \(extra empty field\)") as info:
        read_study(study)
    assert info.value.row == 2
    lines[1] = ",".join([*fields[:-2], "2", "0104", ""])  # the same count as the header: the leading zero is refused
    write_lines(study / "manifest.csv", lines)
    with pytest.raises(InputError, match=r"not a number: '0104' \(a whole number with a leading zero: write 104") as info:
        read_study(study)
    assert info.value.row == 2 and info.value.column == "repetition"


def test_check_lists_every_row_of_the_wrong_width(run_cli, study):
    lines = manifest_lines(study)
    lines[1] += ","
    lines[3] = lines[3].rsplit(",", 1)[0]
    write_lines(study / "manifest.csv", lines)
    code, out, err = run_cli("check", study)
    assert code == 2
    text = out + err
    assert "row 2: 6 fields but the header has 5" in text and "row 4: 4 fields but the header has 5" in text


# --------------------------------------------------------------------------- 6. a quoted header


@pytest.mark.parametrize("cell, message", [
    ("\u0661", "(write the digits 0-9)"), ("\uff13", "(write the digits 0-9)"),
    ('"1,0"', "(a decimal comma: write 1.0)"), ("0", "must be positive"),
])
def test_a_quoted_header_is_read_by_the_number_parser(study, cell, message):
    """28.6: ``"nominal_force_n"`` (R's write.csv quotes every name) skipped the parser: 1 and 3 in other scripts."""
    lines = manifest_lines(study)
    lines[0] = ",".join(f'"{name}"' for name in lines[0].split(",")) + ',"nominal_force_n"'
    lines[1:] = [line + ",2" for line in lines[1:]]
    lines[1] = lines[1][: -len(",2")] + f",{cell}"
    write_lines(study / "manifest.csv", lines)
    with pytest.raises(InputError) as info:
        read_study(study)
    assert message in info.value.message and info.value.column == "nominal_force_n" and info.value.row == 2


# --------------------------------------------------------------------------- 7. duplicate column names


@pytest.mark.parametrize("file, column", [("manifest.csv", "force_n"), ("ratings.csv", "rating"),
                                          ("specimens.csv", "wavelength_mm")])
def test_a_column_named_twice_is_refused(run_cli, study, file, column):
    """28.7: pandas read the second force_n or rating as force_n.1 and it was ignored."""
    path = study / file
    lines = path.read_text().splitlines()
    lines[0] += f", {column}"
    lines[1:] = [line + ",7" for line in lines[1:]]
    write_lines(path, lines)
    line = check_output(run_cli, study)
    assert f"{path}: column '{column}' appears twice in the header" in line


# --------------------------------------------------------------------------- 12. CSV size and width


def test_a_csv_too_large_or_too_wide_is_refused_before_it_is_read(run_cli, study, monkeypatch):
    """28.12: 2 million columns took 97 s and 3.7 GB; a 6 GB sparse ratings.csv ran `check` out of memory."""
    ratings = study / "ratings.csv"
    with ratings.open("r+b") as handle:
        handle.truncate(csv_read.MAX_CSV_BYTES + 1)  # sparse: costs no disk
    line = check_output(run_cli, study)
    assert f"{ratings}: is larger than 100 MB; refusing to read it" in line
    manifest = study / "manifest.csv"
    manifest.write_text(",".join(f"c{i}" for i in range(200_000)) + "\n")
    line = check_output(run_cli, study)
    assert f"{manifest}: has 200000 columns; a study file has at most {csv_read.MAX_CSV_COLUMNS}" in line


# --------------------------------------------------------------------------- 16. the encoding is named


@pytest.mark.parametrize("encoding, name", [("utf-16-le", "UTF-16LE (no byte-order mark)"), ("utf-16", "UTF-16"),
                                            ("utf-16-be", "UTF-16BE (no byte-order mark)")])
def test_a_wide_encoding_is_named(study, encoding, name):
    path = study / "ratings.csv"
    path.write_bytes(path.read_text().encode(encoding))
    problems = Problems()
    load_study(study, problems=problems)
    messages = problems.lines()
    assert any(f"ratings.csv: is {name} text, not UTF-8; save it as UTF-8" in m for m in messages), messages


def test_a_markdown_sheet_with_a_column_named_twice_is_refused(tmp_path):
    """28.7 for the other ratings reader: a filled-in Markdown sheet kept the last of two rating columns."""
    from roughsense.io.ratings_file import read_ratings

    path = tmp_path / "sheet.md"
    path.write_text("| participant | session | specimen | rating | rating |\n|---|---|---|---|---|\n| P1 | 1 | R2 | 5 | 0.5 |\n")
    with pytest.raises(InputError, match="table column 'rating' appears twice in the header") as info:
        read_ratings(path)
    assert info.value.row == 1


# --------------------------------------------------------------------------- 4. specimen specs, 14. seeds

SWEEP = """
[sweep]
seeds = [{seed}]
repetitions = 2
specimens = ["R2", "R3", {spec}]
image_size_px = [480, 160]
max_components = 4
[axes]
pad = ["smooth"]
"""


@pytest.mark.parametrize("spec, message", [
    ("rect:1_5", "not a number: '1_5' (no '_' between digits: write 15)"),
    ("rand:1.5:0.2:1_0", "the seed is not a number: '1_0'"),
    ("sin:3:\u0661", "(write the digits 0-9)"),
    ("rand:1.5:0.2:9223372036854775808", "the seed must be at most 9223372036854775807"),
])
def test_a_specimen_spec_is_read_by_the_number_parser(run_cli, tmp_path, spec, message):
    """28.4: ``rect:1_5`` simulated a 15 mm grating (float() reads digit groups); the seed of rand: is bounded."""
    line = one_error(run_cli, "simulate", "--out", tmp_path / "s", "--specimens", f"R3,{spec}", "--pads", "smooth")
    assert f"specimen '{spec}'" in line and message in line
    assert not (tmp_path / "s").exists()
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SWEEP.format(seed=0, spec=f'"{spec}"'))
    line = one_error(run_cli, "explore", sweep, "--out", tmp_path / "x")
    assert message in line and str(sweep) in line


@pytest.mark.parametrize("args, message", [
    (["--seed", "9223372036854775808"], "--seed must be at most 9223372036854775807"),
    (["--seed", "1e23"], "--seed must be at most 9223372036854775807, got 1e+23"),
])
def test_a_seed_is_bounded_where_it_is_read(run_cli, tmp_path, args, message):
    """28.14: seeds >= 2**63 ended in ArrowInvalid or OverflowError after the work they seeded."""
    line = one_error(run_cli, "simulate", "--out", tmp_path / "s", "--specimens", "R3", *args)
    assert message in line
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SWEEP.format(seed=2**63, spec='"R4"'))
    line = one_error(run_cli, "explore", sweep, "--out", tmp_path / "x")
    assert "[sweep] seeds: expected a whole number from 0 to 9223372036854775807" in line


# --------------------------------------------------------------------------- 5. TOML spellings, on the parsed document


def test_a_multiline_string_does_not_hide_a_toml_spelling(study):
    """28.5: after a multi-line string holding \\\""" the old pattern lost track: px_per_mm = 3_49 read as 349."""
    toml = study / "study.toml"
    text = toml.read_text()
    assert "px_per_mm = 20.0" in text
    toml.write_text(text.replace("[study]\n", '[study]\nnote = """a \\""" px_per_mm = 1 """\n')
                    .replace("px_per_mm = 20.0", "px_per_mm = 2_0") + '# a comment quoting """\n')
    with pytest.raises(InputError, match=r"line \d+: '2_0' is not a number as roughsense reads one \(no '_' between digits"):
        read_study(study)


def test_valid_toml_with_number_like_text_is_accepted(study):
    """28.5: ``1_000`` inside a string and a key named ``inf`` were refused as numbers."""
    toml = study / "study.toml"
    text = toml.read_text()
    toml.write_text(text.replace('name = "tiny"', "name = \"batch 1_000 0x10 inf\"\n# a comment 1_0\ninf = 1.0")
                    + "\n[pads.inf]\nridge_period_mm = 1.5\n[pads.'1_000']\nridge_period_mm = 2e0\n")
    with pytest.warns(Warning, match="unknown key 'inf' in \\[study\\] ignored"):  # a warning, not a refusal
        study_ = read_study(study)
    assert study_.name == "batch 1_000 0x10 inf" and study_.pad_ridge_period_mm == {"inf": 1.5, "1_000": 2.0}


def test_a_sweep_file_is_held_to_the_same_rule(run_cli, tmp_path):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('[sweep]\nname = """x \\""" max_components = 1 """\n' + SWEEP.format(seed=0, spec='"R4"')
                     .replace("[sweep]\n", "").replace("max_components = 4", "max_components = 0x4") + '# """\n')
    line = one_error(run_cli, "explore", sweep, "--out", tmp_path / "x")
    assert "'0x4' is not a number as roughsense reads one" in line


# --------------------------------------------------------------------------- 13. live and capture read max_pixels


def png_claiming(width: int, height: int) -> bytes:
    """A PNG whose header claims ``width`` x ``height`` px (its data is empty: never decoded here)."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"")) + chunk(b"IEND", b""))


@pytest.fixture(scope="module")
def model_2n(tiny, tmp_path_factory):
    from roughsense.cli import main

    path = tmp_path_factory.mktemp("model") / "m.json"
    assert main(["fit", "--study", str(tiny), "--pad", "smooth", "--condition", "2N", "--out", str(path)]) == 0
    return path


def test_live_and_capture_refuse_a_frame_above_max_pixels_before_decoding(run_cli, tmp_path, model_2n):
    """28.13: a 16000 x 15000 PNG peaked at 1.9 GB (predict --live) and 3.2 GB (capture, which wrote it)."""
    big = tmp_path / "big.png"
    big.write_bytes(png_claiming(16000, 15000))
    pattern = tmp_path / "frames"
    pattern.mkdir()
    (pattern / "f_0000.png").write_bytes(png_claiming(16000, 15000))
    for source in (big, pattern / "f_%04d.png"):
        line = one_error(run_cli, "predict", model_2n, "--live", "--source", source, "--max-frames", "1")
        assert "image is 16000 x 15000 px (240 Mpx), above the limit of 100 Mpx" in line
        line = one_error(run_cli, "capture", "--source", source, "--out", tmp_path / "captured", "--specimen", "R2",
                         "--pad", "smooth")
        assert "image is 16000 x 15000 px (240 Mpx), above the limit of 100 Mpx" in line
        assert not (tmp_path / "captured").exists()


def test_a_frame_above_the_studys_max_pixels_is_not_written(tiny):
    import numpy as np

    from roughsense.io.sensor_settings import SensorSettings
    from roughsense.rig.camera import open_source
    from roughsense.rig.capture import _check_frame

    image = next((tiny / "images").iterdir())
    with pytest.raises(InputError, match=r"frames? is 600 ?x ?64 px|image is 600 x 64 px"):
        open_source(image, max_pixels=1000)
    with open_source(image) as frames:
        frame = frames.read_fresh()
    with pytest.raises(InputError, match="above the study's \\[sensor\\] max_pixels of 0.001 Mpx; nothing of it was written"):
        _check_frame(frame, SensorSettings(max_pixels=1000), frames)
    _check_frame(frame, SensorSettings(roi=(0, 0, 600, 64)), frames)
    assert np.asarray(frame).shape == (64, 600, 3)


@pytest.mark.parametrize("value", ["1e300", "1073741825", "2e9"])
def test_a_pixel_limit_beyond_what_opencv_decodes_is_refused(study, value):
    """28.16: ``[sensor] max_pixels = 1e300`` was accepted."""
    toml = study / "study.toml"
    toml.write_text(toml.read_text().replace("[sensor]\n", f"[sensor]\nmax_pixels = {value}\n"))
    with pytest.raises(InputError, match=r"\[sensor\] max_pixels must be a whole number of pixels from 1 to 1073741824"):
        read_study(study)


# --------------------------------------------------------------------------- 15. --out equal to an input


def test_an_output_that_is_an_input_is_refused_even_with_force(run_cli, study, tmp_path, model_2n):
    """28.15: `ratings r.csv --out r.csv --force` replaced the raw ratings; fit and predict destroyed their inputs."""
    model = tmp_path / "m.json"
    shutil.copy(model_2n, model)
    image = next((study / "images").iterdir())
    cases = [
        (["ratings", study / "ratings.csv", "--out", study / "ratings.csv"], study / "ratings.csv"),
        (["fit", "--study", study, "--pad", "smooth", "--condition", "2N", "--out", study / "manifest.csv"],
         study / "manifest.csv"),
        (["predict", model, image, "--out", model], model),
        (["predict", model, image, "--out", image], image),
        (["predict", model, "--study", study, "--out", study / "images" / "x.csv"], study / "images"),
        (["features", image, "--out", image], image),
        (["features", "--study", study, "--out", study / "specimens.csv"], study / "specimens.csv"),
        (["protocol", "--seed", "1", "--specimens", study / "specimens.csv", "--out", study / "specimens.csv"],
         study / "specimens.csv"),
        (["study", "--study", study, "--out", study], study),
    ]
    for args, victim in cases:
        before = victim.read_bytes() if victim.is_file() else None
        line = one_error(run_cli, *args, "--force")
        assert "--force does not change this" in line and "--out" in line, line
        if before is not None:
            assert victim.read_bytes() == before, args
    link = tmp_path / "link.json"
    link.hardlink_to(model)  # the same file under another name
    line = one_error(run_cli, "predict", model, image, "--out", link, "--force")
    assert f"is an input of this run {model}" in line


# --------------------------------------------------------------------------- 16. minor


def test_check_lists_every_file_name_too_long(run_cli, study):
    """28.16: `check` stopped at the first "File name too long" instead of listing every row."""
    lines = manifest_lines(study)
    for k, letter in ((1, "x"), (3, "y")):
        fields = lines[k].split(",")
        fields[0] = f"images/{letter * 300}.png"
        lines[k] = ",".join(fields)
    write_lines(study / "manifest.csv", lines)
    text = check_output(run_cli, study)
    for row in (2, 4):
        assert f"manifest.csv, row {row}, column 'image': image file cannot be looked up (File name too long)" in text
