"""The CLI's input contract on damaged study folders and edited model files (issue 10), fuzzed: whatever the input,
the outcome is boring.

A small valid study (4 specimens x 2 repetitions x 3 forces, 400 x 30 px images, built once per module with the
simulator) is copied per example and mutated by hypothesis: CSV cells, headers and rows, encodings, study.toml values
and tables, image bytes, and names with path characters. Then a command runs in-process (features --study, fit,
ratings, protocol, predict --study, study). The outcome must be exit 0 or exit 2 with exactly one ``roughsense: error:``
line; every stderr line is roughsense's own (warnings, notes, stage lines), never a traceback, an internal error or a
library's message; and nothing outside ``--out`` (and the cache) may change.

Budget: the module runs in well under a minute (fixed ``max_examples``, derandomised by the conftest profile).
"""
from __future__ import annotations

import contextlib
import csv
import io
import os
import shutil
import struct
import tempfile
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from roughsense.model.peak_law.file import OPTIONAL_FIELDS
from roughsense.sim.config import SimulationConfig, with_image_size
from roughsense.sim.simulate import simulate_study
from tests.fuzzing import EXAMPLES, FUZZ

CSV_FILES = ("manifest.csv", "specimens.csv", "ratings.csv")


HOSTILE_CELLS = [
    "", " ", "nan", "NaN", "inf", "-inf", "-1", "0", "0.0", "1e308", "1e-320", "true", "True", "99999999999999999999",
    "../x", "/etc/passwd", "a/../../../x/keep", "images/../../x.png", "./images", "images", ".hidden", "-rf", "R3",
    "R2", "smooth", "P01", "1,2", '"', "'", "\\", "C:\\x", "é", "\u202e", "x" * 300, "1N", "images/*.png", "\x00",
    "line\nbreak", "2", "3.0", "rectangular", "other", "sinusoidal", "images/smooth_R2_1N_r01.png",
    "./images/smooth_R2_1N_r01.png", "images//smooth_R2_2N_r01.png",
    "1_0", "\u0661", "\u0663.\u0665", "0x10", "1e6", "1e-7", " 2 ", "2.01 N", "0,5", "+.5", "5.",  # issue 22: spellings
    "0104", "007", "-01", "00", "2,0104",  # issue 28: leading zeros of a decimal comma's split
]


HOSTILE_HEADERS = ['"force_n"', '"nominal_force_n"', "nominal_force_n", "0.1", "3", "nan", "Infinity", "0.0795",
                   "spectrum@0.1", "force_n", "rating", "image", "timestamp", " repetition "]


TOML_VALUES = [
    "true", "false", "0", "-1", "1e308", "nan", "inf", "-inf", '"center"', '"auto"', '"1,2,3,4"', '""', "[]", "[true, 2, 3]",
    "[1, 2, 3]", "[0, 0, 1900, 150]", "[0, 10, 400, 10]", "[1e308, 1, 1]", "[[1]]", "{a = 1}", '"../x"', '"R2"',
    '"a/../../b"', "1", "34.9", "2", "100", "100000000000000000000", '"x"', "[0, 10, 400, 1000]", '"3"', "0.5", "[2.0]",
]


TOML_KEYS = {
    "study": ("name", "reference_specimen", "nme"),
    "sensor": ("px_per_mm", "roi", "max_pixels", "roi_typo"),
    "protocol": ("forces_n", "force"),
    "simulation": ("seed", "anything"),
    "other": ("x",),
}


RENAMES = ["R2", "a/b", "../R2", ".R2", "R 2", "R2:3", "r2", "C2", "x" * 70, "R2\\x", "Ŕ2", "R2.", "-R2", "2"]


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


BOMB = b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", struct.pack(">IIBBBBB", 60000, 60000, 8, 0, 0, 0, 0)) \
    + _chunk(b"IDAT", zlib.compress(b"")) + _chunk(b"IEND", b"")


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """The simulator's study on a 400 x 30 px crop of its frames, with the ROI moved to match."""
    root = tmp_path_factory.mktemp("fuzz") / "study"
    config = SimulationConfig(pads=("smooth",), specimens=("R2", "R3", "R4", "C2"), repetitions=2, seed=5,
                              participants=2, sessions=1)
    simulate_study(root, with_image_size(config, 1920, 170), jobs=1)
    for path in sorted((root / "images").iterdir()):
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        assert cv2.imwrite(str(path), image[70:100, 760:1160])
    toml = root / "study.toml"
    toml.write_text(toml.read_text().replace('roi = "center"', "roi = [0, 10, 400, 10]"))
    return root


def _rows(path: Path) -> list[list[str]]:
    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.reader(handle))


def _write_rows(path: Path, rows: list[list[str]]) -> None:
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerows(rows)
    path.write_bytes(buffer.getvalue().encode("utf-8", errors="surrogatepass"))


def set_cell(file, row, column, value):
    def apply(root: Path) -> None:
        rows = _rows(root / file)
        r = rows[row % len(rows)]
        if r:
            r[column % len(r)] = value
        _write_rows(root / file, rows)
    return apply


def table_edit(file, kind, index):
    def apply(root: Path) -> None:
        rows = _rows(root / file)
        i = index % len(rows)
        if kind == "drop_row" and len(rows) > 1:
            del rows[max(i, 1)]
        elif kind == "dup_row":
            rows.insert(i, list(rows[i]))
        elif kind == "blank_line":
            rows.insert(i, [])
        elif kind == "extra_field":
            rows[i] = [*rows[i], "surplus"]
        elif kind == "extra_blank":  # issue 28: a blank field beyond the header counts too
            rows[i] = [*rows[i], ""]
        elif kind == "short_row":
            rows[i] = rows[i][:-1]
        elif kind == "drop_column":
            j = index % len(rows[0])
            rows = [[c for k, c in enumerate(r) if k != j] for r in rows]
        elif kind == "dup_column":
            j = index % len(rows[0])
            rows = [[*r, r[j]] if j < len(r) else r for r in rows]
        elif kind == "header_only":
            rows = rows[:1]
        elif kind == "empty":
            rows = []
        _write_rows(root / file, rows)
    return apply


def raw_edit(file, kind, fraction, data):
    def apply(root: Path) -> None:
        path = root / file
        raw = path.read_bytes() if path.is_file() else b""
        cut = int(len(raw) * fraction)
        if kind == "truncate":
            raw = raw[:cut]
        elif kind == "latin1":
            raw = raw.decode("utf-8", errors="replace").replace("R", "\xc9", 1).encode("latin-1", errors="replace")
        elif kind == "utf16":
            raw = raw.decode("utf-8", errors="replace").encode("utf-16")
        elif kind == "bom":
            raw = b"\xef\xbb\xbf" + raw
        elif kind == "crlf":
            raw = raw.replace(b"\n", b"\r\n")
        elif kind == "splice":
            raw = raw[:cut] + data + raw[cut:]
        elif kind == "overwrite":
            raw = raw[:cut] + data + raw[cut + len(data):]
        elif kind == "delete":
            path.unlink(missing_ok=True)
            return
        elif kind == "folder":
            path.unlink(missing_ok=True)
            path.mkdir()
            return
        path.write_bytes(raw)
    return apply


def toml_set(table, key, value):
    def apply(root: Path) -> None:
        path = root / "study.toml"
        lines = path.read_text(encoding="utf-8").splitlines()
        header = f"[{table}]"
        if header not in lines:
            lines += ["", header]
        start = lines.index(header)
        for i in range(start + 1, len(lines)):
            if lines[i].startswith("["):
                break
            if lines[i].split("=")[0].strip() == key:
                lines[i] = f"{key} = {value}"
                break
        else:
            lines.insert(start + 1, f"{key} = {value}")
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return apply


def toml_table_as_value(table, value):
    def apply(root: Path) -> None:
        path = root / "study.toml"
        text = path.read_text(encoding="utf-8").replace(f"[{table}]", "[dropped_" + table + "]")
        path.write_text(f"{table} = {value}\n" + text, encoding="utf-8")
    return apply


def toml_nested(depth):
    def apply(root: Path) -> None:
        with (root / "study.toml").open("a", encoding="utf-8") as handle:
            handle.write(f"\n[deep]\nx = {'[' * depth}{']' * depth}\n")
    return apply


def image_edit(index, kind, fraction, data):
    def apply(root: Path) -> None:
        images = sorted((root / "images").iterdir())
        path = images[index % len(images)]
        raw = path.read_bytes() if path.is_file() else b""
        cut = int(len(raw) * fraction)
        if kind == "truncate":
            path.write_bytes(raw[:cut])
        elif kind == "flip":
            if raw:
                at = min(cut, len(raw) - 1)
                path.write_bytes(raw[:at] + bytes([raw[at] ^ 0xFF]) + raw[at + 1:])
        elif kind == "bomb":
            path.write_bytes(BOMB)
        elif kind == "garbage":
            path.write_bytes(data)
        elif kind in ("jpeg", "tiff", "bmp", "png16"):  # another format (or depth), then maybe cut short
            image = cv2.imdecode(np.frombuffer(raw, "uint8"), cv2.IMREAD_UNCHANGED)
            if image is not None:
                if kind == "png16":
                    image = image.astype(np.uint16) * 257
                encoded = cv2.imencode({"jpeg": ".jpg", "tiff": ".tif", "bmp": ".bmp", "png16": ".png"}[kind],
                                       image)[1].tobytes()
                path.write_bytes(encoded if fraction > 0.5 else encoded[: int(len(encoded) * fraction * 2)])
        elif kind == "tiny":
            path.write_bytes(cv2.imencode(".png", np.zeros((3, 3), "uint8"))[1].tobytes())
        elif kind == "delete":
            path.unlink()
        elif kind == "symlink_out":
            path.unlink()
            path.symlink_to(root.parent / "outside" / "keep.png")
        elif kind == "folder":
            path.unlink()
            path.mkdir()
    return apply


def add_column(file, header, cell):
    """Issue 28: a column added with a hostile header (quoted, a number, a duplicate) and one value in every row."""
    def apply(root: Path) -> None:
        rows = _rows(root / file)
        if rows:
            _write_rows(root / file, [[*rows[0], header], *([*r, cell] if r else r for r in rows[1:])])
    return apply


def quote_all(file):
    """Issue 28: every field quoted, headers included, as R's write.csv saves a table."""
    def apply(root: Path) -> None:
        rows = _rows(root / file)
        buffer = io.StringIO()
        csv.writer(buffer, lineterminator="\n", quoting=csv.QUOTE_ALL).writerows(rows)
        (root / file).write_bytes(buffer.getvalue().encode("utf-8", errors="surrogatepass"))
    return apply


def rename_everywhere(column, old, new):
    """Rename a pad/specimen/participant in every file (consistent data whose only fault is the name)."""
    def apply(root: Path) -> None:
        for file in CSV_FILES:
            rows = _rows(root / file)
            if column in rows[0]:
                j = rows[0].index(column)
                for r in rows[1:]:
                    if len(r) > j and r[j] == old:
                        r[j] = new
                _write_rows(root / file, rows)
    return apply


cells = st.one_of(st.sampled_from(HOSTILE_CELLS), st.text(max_size=8), st.integers(-(10**22), 10**22).map(str),
                  st.floats().map(repr))


blobs = st.one_of(st.binary(max_size=40), st.sampled_from([BOMB, b"\x00" * 20, "é".encode("latin-1"), b"\xff\xfe"]))


fractions = st.floats(0, 1)


mutations = st.one_of(
    st.builds(set_cell, st.sampled_from(CSV_FILES), st.integers(0, 40), st.integers(0, 10), cells),
    st.builds(table_edit, st.sampled_from(CSV_FILES),
              st.sampled_from(["drop_row", "dup_row", "blank_line", "extra_field", "extra_blank", "short_row",
                               "drop_column", "dup_column", "header_only", "empty"]), st.integers(0, 40)),
    st.builds(add_column, st.sampled_from(CSV_FILES), st.sampled_from(HOSTILE_HEADERS), cells),
    st.builds(quote_all, st.sampled_from(CSV_FILES)),
    st.builds(raw_edit, st.sampled_from([*CSV_FILES, "study.toml"]),
              st.sampled_from(["truncate", "latin1", "utf16", "bom", "crlf", "splice", "overwrite", "delete", "folder"]),
              fractions, blobs),
    st.builds(lambda table, index, value: toml_set(table, TOML_KEYS[table][index % len(TOML_KEYS[table])], value),
              st.sampled_from(sorted(TOML_KEYS)), st.integers(0, 3), st.sampled_from(TOML_VALUES)),
    st.builds(toml_table_as_value, st.sampled_from(["study", "sensor", "protocol", "simulation"]),
              st.sampled_from(["3", '"x"', "[1, 2]", "true"])),
    st.builds(toml_nested, st.sampled_from([2, 50, 3000])),
    st.builds(image_edit, st.integers(0, 30),
              st.sampled_from(["truncate", "flip", "bomb", "garbage", "jpeg", "tiff", "bmp", "png16", "tiny", "delete",
                               "symlink_out", "folder"]),
              fractions, blobs),
    st.builds(rename_everywhere, st.sampled_from(["pad", "specimen", "participant"]),
              st.sampled_from(["smooth", "R2", "P01"]), st.sampled_from(RENAMES)),
)


@pytest.fixture
def run_cli(capfd):
    """Like conftest's run_cli, but capturing file descriptors 1 and 2: a codec library writing to stderr
    directly (libpng, libjpeg, libtiff) would break the one-line promise without passing through Python."""
    from roughsense.cli import main

    def _run(*args):
        capfd.readouterr()
        code = main([str(a) for a in args])
        captured = capfd.readouterr()
        return code, captured.out, captured.err

    return _run


def snapshot(root: Path) -> dict[str, tuple]:
    """Every entry under ``root``: kind, size and mtime (a change anywhere shows)."""
    entries = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            path = Path(dirpath, name)
            stat = path.lstat()
            entries[str(path.relative_to(root))] = (stat.st_mode, stat.st_size, stat.st_mtime_ns)
    return entries


def assert_boring(code: int, err: str) -> None:
    """Exit 0 or 2; every stderr line is roughsense's own (warnings, notes, stage lines such as
    ``roughsense: writing the report ... done in 3.1 s``), and exit 2 has exactly one ``roughsense: error:`` line."""
    assert "Traceback" not in err and "internal error" not in err, err
    assert code in (0, 2), (code, err)
    lines = err.splitlines()
    assert all(line.startswith("roughsense: ") for line in lines), err
    errors = [line for line in lines if line.startswith("roughsense: error: ")]
    assert len(errors) == (1 if code == 2 else 0), err


@contextlib.contextmanager
def example_folder(base: Path):
    """A fresh tmp folder per example: study/ (the copy), outside/keep.png (a target to attack), out/ (allowed)."""
    top = Path(tempfile.mkdtemp(prefix="roughsense-fuzz-"))
    try:
        study = shutil.copytree(base, top / "study", symlinks=True)
        (top / "outside").mkdir()
        shutil.copy(next((base / "images").iterdir()), top / "outside" / "keep.png")
        yield top, study
    finally:
        shutil.rmtree(top, ignore_errors=True)


def command_args(command: str, study: Path, out: Path, model: Path | None = None) -> list:
    if command == "features":
        return ["features", "--study", study, "--out", out / "features.csv"]
    if command == "fit":
        return ["fit", "--model", "pls", "--study", study, "--pad", "smooth", "--condition", "2N", "--out",
                out / "model.json"]
    if command == "fit-combined":
        return ["fit", "--model", "pls", "--study", study, "--pad", "smooth", "--condition", "combined", "--cv", "loso",
                "--out", out / "model.json"]
    if command == "ratings":
        return ["ratings", study / "ratings.csv", "--out", out / "summary.csv", "--specimens", study / "specimens.csv"]
    if command == "protocol":
        return ["protocol", "--out", out / "schedule.csv", "--seed", "1", "--participants", "2", "--sessions", "1",
                "--specimens", study / "specimens.csv"]
    if command == "predict":
        return ["predict", model, "--study", study, "--out", out / "predictions.csv"]
    if command == "study":
        return ["study", "--study", study, "--out", out / "report", "--max-components", "2", "--no-loso", "--jobs", "1"]
    raise AssertionError(command)


def run_example(run_cli, base: Path, changes, command: str, monkeypatch, model: Path | None = None) -> None:
    with example_folder(base) as (top, study):
        for change in changes:
            try:
                change(study)
            except (OSError, UnicodeError, ValueError, IndexError, ZeroDivisionError, csv.Error, cv2.error):
                pass  # an earlier change left nothing this one can edit (a deleted file, a folder, other bytes)
        out = top / "out"
        monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(top / "cache"))
        before = snapshot(top)
        code, _, err = run_cli(*command_args(command, study, out, model))
        event(f"{command}: exit {code}")  # pytest --hypothesis-show-statistics shows how often each outcome occurs
        assert_boring(code, err)
        after = snapshot(top)
        changed = {k for k in before.keys() | after.keys() if before.get(k) != after.get(k)}
        outside = sorted(k for k in changed if not k.startswith(("out", "cache")))
        assert outside == [], f"{command} changed {outside} outside --out (exit {code}: {err})"


NO_RAW_WARNINGS = pytest.mark.filterwarnings("error", "default::roughsense.errors.RoughsenseWarning")


@pytest.fixture(scope="module")
def combined_model(base, tmp_path_factory):
    """A combined-force model of the undamaged study, for ``predict --study`` on damaged copies."""
    from roughsense.cli import main

    path = tmp_path_factory.mktemp("combined") / "model.json"
    assert main(["fit", "--model", "pls", "--study", str(base), "--pad", "smooth", "--condition", "combined", "--out",
                 str(path)]) == 0
    return path


@pytest.mark.slow
@NO_RAW_WARNINGS
@FUZZ
@given(changes=st.lists(mutations, min_size=1, max_size=3),
       command=st.sampled_from(["features", "fit", "fit-combined", "ratings", "protocol", "predict"]))
def test_damaged_study_folders_give_boring_outcomes(run_cli, base, combined_model, monkeypatch, changes, command):
    run_example(run_cli, base, changes, command, monkeypatch, combined_model)


@pytest.mark.slow
@NO_RAW_WARNINGS
@settings(FUZZ, max_examples=max(8, EXAMPLES // 10))
@given(changes=st.lists(mutations, min_size=1, max_size=2))
def test_the_study_command_on_damaged_folders_is_boring(run_cli, base, monkeypatch, quick_figures, changes):
    run_example(run_cli, base, changes, "study", monkeypatch)


@pytest.mark.slow
@NO_RAW_WARNINGS
def test_the_undamaged_base_passes_every_command(run_cli, base, combined_model, monkeypatch, quick_figures):
    """The fuzz starts from a folder every command accepts (else it would only ever test refusals)."""
    for command in ("features", "fit", "fit-combined", "ratings", "protocol", "predict", "study"):
        with example_folder(base) as (top, study):
            monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(top / "cache"))
            code, _, err = run_cli(*command_args(command, study, top / "out", combined_model))
            assert code == 0, (command, err)
            assert_boring(code, err)
            assert not [line for line in err.splitlines() if line.startswith("roughsense: warning:")], err


json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-(10**20), 10**20), st.floats(allow_nan=False, allow_infinity=False),
              st.text(max_size=6)),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=4), inner, max_size=3)),
    max_leaves=12,
)


@pytest.fixture(scope="module")
def model_document(base, tmp_path_factory):
    import json

    from roughsense.cli import main

    path = tmp_path_factory.mktemp("model") / "m.json"
    assert main(["fit", "--model", "pls", "--study", str(base), "--pad", "smooth", "--condition", "2N", "--out",
                 str(path)]) == 0
    return json.loads(path.read_text())


def _locations(node, prefix=()):
    """Every (container, key) in a JSON document, so an edit can reach any depth."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, child in items:
        yield prefix + (key,)
        yield from _locations(child, prefix + (key,))


@pytest.mark.slow
@NO_RAW_WARNINGS
@settings(FUZZ, max_examples=max(60, EXAMPLES))
@given(data=st.data(), resign=st.booleans(), delete=st.booleans())
def test_edited_model_files_load_or_are_refused_in_one_message(base, model_document, data, resign, delete):
    """Any edit of a model file, even one whose checksum is recomputed, loads or raises ModelFileError; a model
    that loads scores an image or refuses with a RoughsenseError (its feature definition is checked)."""
    import json

    from roughsense.errors import ModelFileError, RoughsenseError
    from roughsense.model.modelfile import _digest, load_model
    from roughsense.model.reading import model_spectrum

    document = json.loads(json.dumps(model_document))
    places = list(_locations(document))
    where = data.draw(st.sampled_from(places))
    parent = document
    for key in where[:-1]:
        parent = parent[key]
    if delete:
        del parent[where[-1]]
    else:
        parent[where[-1]] = data.draw(json_values)
    if resign and isinstance(document, dict):
        try:
            document["sha256"] = _digest(document)
        except (TypeError, ValueError):
            pass
    path = Path(tempfile.mkdtemp(prefix="roughsense-model-")) / "m.json"
    try:
        path.write_text(json.dumps(document))
        try:
            loaded = load_model(path)
        except ModelFileError as exc:
            assert "\n" not in str(exc) and str(path) in str(exc)
        else:
            assert loaded.n_components >= 1 and loaded.coef_path_.shape == (loaded.n_features, loaded.intercept_path_.size)
            image = sorted((base / "images").glob("*_2N_*.png"))[0]
            try:
                score = loaded.predict(model_spectrum(loaded).transform([image]))
            except RoughsenseError as exc:
                assert "\n" not in str(exc)
            else:
                assert score.shape == (1,) and np.all(np.isfinite(score))  # issue 22: bounded fields, finite scores
    finally:
        shutil.rmtree(path.parent, ignore_errors=True)


ALWAYS_REFUSED = [float("nan"), float("inf"), float("-inf"), 1e308, True, "1"]


SOMETIMES_ACCEPTED = [-1, None]


@pytest.fixture(scope="module")
def law_document(base, tmp_path_factory):
    import json

    from roughsense.cli import main

    path = tmp_path_factory.mktemp("law") / "law.json"
    assert main(["fit", "--study", str(base), "--pad", "smooth", "--condition", "2N", "--model", "peak-law",
                 "--out", str(path)]) == 0
    return json.loads(path.read_text())


@st.composite
def law_edits(draw, section: dict):
    """(where, what, must_refuse): an edit of one field of a law's section, or of one entry of a list field."""
    field = draw(st.sampled_from(sorted(section)))
    value = section[field]
    kind = draw(st.sampled_from(["drop", "set", "set-entry", "length"] if isinstance(value, list) else ["drop", "set"]))
    if kind == "drop":  # only a field older files lack may be missing
        return (field,), "drop", field not in OPTIONAL_FIELDS
    if kind == "length":
        longer = draw(st.booleans())
        return (field,), (value + [0.0] if longer else value[:-1]), True
    replacement = draw(st.sampled_from(ALWAYS_REFUSED + SOMETIMES_ACCEPTED))
    where = (field, draw(st.integers(0, len(value) - 1))) if kind == "set-entry" else (field,)
    return where, replacement, replacement in ALWAYS_REFUSED or replacement is None and field != "pad_ridge_period_mm"


@pytest.mark.slow
@NO_RAW_WARNINGS
@settings(FUZZ, max_examples=max(60, EXAMPLES))
@given(data=st.data())
def test_edited_peak_law_files_are_refused_by_their_field_checks(run_cli, base, law_document, tmp_path_factory, data):
    """Any edit of a law's field, re-signed (the checksum is unkeyed), is refused by ``predict`` in one line naming
    the file, or -- where the value is one the field accepts -- predicts finite numbers."""
    import json

    import pandas as pd

    from roughsense.model.modelfile import _digest

    document = json.loads(json.dumps(law_document))
    where, value, must_refuse = data.draw(law_edits(document["model"]))
    parent = document["model"]
    for key in where[:-1]:
        parent = parent[key]
    if value == "drop":
        del parent[where[-1]]
    else:
        parent[where[-1]] = value
    try:
        document["sha256"] = _digest(document)
    except ValueError:  # NaN or infinity: the canonical JSON refuses them, so the old checksum stays
        pass
    folder = Path(tempfile.mkdtemp(prefix="roughsense-law-"))
    try:
        path, out = folder / "law.json", folder / "p.csv"
        path.write_text(json.dumps(document))
        image = sorted((base / "images").glob("*_2N_*.png"))[0]
        code, _, err = run_cli("predict", path, image, "--out", out)
        event(f"peak-law edit: exit {code}")
        assert_boring(code, err)
        if code == 2:
            assert len(err.splitlines()) == 1 and str(path) in err, err
        else:
            assert not must_refuse, (where, value)
            assert np.all(np.isfinite(pd.read_csv(out).filter(like="roughness_rel_").iloc[:, 0].to_numpy(dtype=float)))
    finally:
        shutil.rmtree(folder, ignore_errors=True)
