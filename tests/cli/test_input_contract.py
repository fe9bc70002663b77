"""The study contract against hostile input (issue 10): names, image paths, decompression bombs, the feature
cache, malformed tables and TOML, and weak validation. Every refusal is one stderr line and exit 2."""
from __future__ import annotations

import json
import os
import shutil
import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from roughsense._util import cache
from roughsense.errors import InputError
from roughsense.io.images import header_size
from roughsense.io.names import NAME_MAX_CHARS, check_name, is_safe_name
from roughsense.io.sensor_settings import SensorSettings
from roughsense.io.study import read_study
from roughsense.io.study_config import read_config
from roughsense.io.toml_write import dump_toml
from roughsense.io.writer import StudyWriter
from roughsense.sim.config import SimulationConfig, with_image_size
from roughsense.sim.simulate import simulate_study

FORCES_TOML = "forces_n = [\n    1.0,\n    2.0,\n    3.0,\n]"  # the writer's study.toml (tomli-w: an item a line)

SPECIMENS = ("R2", "R3", "R4", "C2")


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    config = SimulationConfig(pads=("smooth",), specimens=SPECIMENS, repetitions=2, seed=3, participants=3, sessions=2)
    return simulate_study(tmp_path_factory.mktemp("base") / "study", with_image_size(config, 1920, 170), jobs=1)


@pytest.fixture()
def sandbox(base, tmp_path):
    """A copy of the study inside ``tmp_path/box``, with the report folder beside it."""
    root = shutil.copytree(base, tmp_path / "box" / "study")
    return root


def tree(root: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``root`` with its size and mtime: what a run may not change outside its --out."""
    return {str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in root.rglob("*") if p.is_file() or p.is_symlink()}


def study_error(run_cli, root: Path, out: Path) -> str:
    """``study``'s one error line for a folder problem, without the pointer to ``check`` it ends with (checked here)."""
    line = one_error(*run_cli(*study_args(root, out))[::2])
    hint = f"; run `roughsense check {root}` to list every problem"
    assert line.endswith(hint), line
    return line.removesuffix(hint)


def one_error(code: int, err: str) -> str:
    """The one error line of a refused run (warnings and stage lines may precede it, all roughsense's own)."""
    assert code == 2, err
    assert "Traceback" not in err and all(line.startswith("roughsense: ") for line in err.splitlines()), err
    lines = [line for line in err.splitlines() if line.startswith("roughsense: error: ")]
    assert len(lines) == 1, err
    return lines[0]


def edit_csv(path: Path, row: int, column: str, value: str) -> None:
    """Set one cell (``row`` is the file line, 2 = first data row), keeping everything else as text."""
    frame = pd.read_csv(path, dtype=str, keep_default_na=False)
    frame.loc[row - 2, column] = value
    frame.to_csv(path, index=False)


def study_args(root: Path, out: Path) -> list:
    return ["study", "--study", root, "--out", out, "--max-components", "2", "--no-loso"]


# --------------------------------------------------------------------------- 1. one name rule


def test_a_pad_with_path_characters_is_refused_and_nothing_is_written_outside_out(run_cli, sandbox, tmp_path, monkeypatch):
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    edit_csv(sandbox / "manifest.csv", 2, "pad", "a/../../../x/keep")
    before = tree(tmp_path / "box")
    out = tmp_path / "box" / "report"
    line = one_error(*run_cli(*study_args(sandbox, out))[::2])
    assert "manifest.csv, row 2, column 'pad'" in line and "'a/../../../x/keep'" in line
    assert tree(tmp_path / "box") == before
    assert not out.exists() and not (tmp_path / "x").exists()


@pytest.mark.parametrize("file, column", [("specimens.csv", "specimen"), ("ratings.csv", "participant"),
                                          ("ratings.csv", "session"), ("manifest.csv", "specimen")])
@pytest.mark.parametrize("bad", ["../up", ".hidden", "a b", "-opt", "x" * 65, "C:\\win", "é"])
def test_every_name_read_from_a_table_follows_the_rule(sandbox, file, column, bad):
    edit_csv(sandbox / file, 3, column, bad)
    with pytest.raises(InputError) as caught:
        read_study(sandbox)
    error = caught.value
    assert (error.path.name, error.row, error.column) == (file, 3, column)


def test_the_reference_specimen_from_toml_follows_the_rule(sandbox):
    text = (sandbox / "study.toml").read_text().replace('reference_specimen = "R3"', 'reference_specimen = "../R3"')
    (sandbox / "study.toml").write_text(text)
    with pytest.raises(InputError, match="reference_specimen '../R3' is not allowed"):
        read_study(sandbox)


@given(st.text(min_size=0, max_size=80))
@settings(max_examples=300)
def test_a_safe_name_is_always_one_plain_file_name(name):
    if is_safe_name(name):
        assert 1 <= len(name) <= NAME_MAX_CHARS
        assert name not in (".", "..") and not name.startswith((".", "-"))
        assert Path("/base", name).parent == Path("/base") and "/" not in name and "\\" not in name
        assert name.isascii() and name.isprintable()
        assert check_name(name) == name
    else:
        with pytest.raises(InputError, match="is not allowed"):
            check_name(name, path="f.csv", row=4, column="pad")


def test_paper_and_simulator_names_are_safe():
    from roughsense.paper import PAPER_SPECIMENS
    from roughsense.sim.specimens import parse_specimen

    assert all(is_safe_name(n) for n in (*PAPER_SPECIMENS, "smooth", "fingerprint", "P01", "1", "2.5N"))
    assert parse_specimen("sin:3:0.5").name == "sin_3_0.5"
    assert parse_specimen("rand:1.5:0.2:7").name == "rand_1.5_0.2_7"


# --------------------------------------------------------------------------- 2. image paths


@pytest.mark.parametrize("image, why", [
    ("/etc/passwd", "absolute path"),
    ("images/../../outside.png", "leads outside the study folder"),
    ("../study/images/x.png", "leads outside the study folder"),
    ("C:/images/x.png", "absolute path"),
])
def test_manifest_paths_outside_the_folder_are_refused_by_row(run_cli, sandbox, tmp_path, image, why):
    edit_csv(sandbox / "manifest.csv", 4, "image", image)
    line = one_error(*run_cli("features", "--study", sandbox, "--out", tmp_path / "f.csv")[::2])
    assert "manifest.csv, row 4, column 'image'" in line and why in line


def test_a_symlink_leading_out_of_the_folder_is_refused(sandbox, tmp_path):
    outside = tmp_path / "secret.png"
    shutil.copy(next((sandbox / "images").iterdir()), outside)
    (sandbox / "images" / "link.png").symlink_to(outside)
    edit_csv(sandbox / "manifest.csv", 5, "image", "images/link.png")
    with pytest.raises(InputError, match="leads outside the study folder") as caught:
        read_study(sandbox)
    assert (caught.value.row, caught.value.column) == (5, "image")


def test_a_symlink_inside_the_folder_is_fine(sandbox):
    frame = pd.read_csv(sandbox / "manifest.csv", dtype=str)
    target = sandbox / frame.loc[0, "image"]
    moved = sandbox / "images" / "real.png"
    target.rename(moved)
    target.symlink_to(moved)
    assert len(read_study(sandbox).manifest) == len(frame)


def test_two_rows_naming_one_file_are_refused(sandbox):
    frame = pd.read_csv(sandbox / "manifest.csv", dtype=str)
    edit_csv(sandbox / "manifest.csv", 7, "image", "./" + frame.loc[2, "image"])
    with pytest.raises(InputError, match="names the same file as row 4") as caught:
        read_study(sandbox)
    assert caught.value.row == 7


# --------------------------------------------------------------------------- 3. decompression bombs


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png_claiming(width: int, height: int, idat: bytes = zlib.compress(b"")) -> bytes:
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header) + _chunk(b"IDAT", idat) + _chunk(b"IEND", b"")


def real_gray_png(width: int, height: int) -> bytes:
    """A complete, valid all-black PNG, compressed row by row (never held whole in memory)."""
    packer = zlib.compressobj(9)
    row = b"\x00" * (width + 1)
    body = b"".join(packer.compress(row) for _ in range(height)) + packer.flush()
    return png_claiming(width, height, body)


@pytest.fixture()
def no_decoding(monkeypatch):
    """Fail the test if anything tries to decode pixels."""
    import roughsense.io.images as images
    import roughsense.sensor.line as sensor  # imported first: it binds decode_png_top_rows by name

    def refuse(*args, **kwargs):
        raise AssertionError("an image was decoded")

    monkeypatch.setattr(images, "_opencv", refuse)
    for module in (images, sensor):
        monkeypatch.setattr(module, "decode_png_top_rows", refuse)


def test_a_tiny_png_claiming_60000_squared_pixels_is_refused_before_decoding(run_cli, tmp_path, no_decoding):
    bomb = tmp_path / "bomb.png"
    bomb.write_bytes(png_claiming(60000, 60000, zlib.compress(b"\x00" * 4)))  # the first row's start, then nothing
    assert bomb.stat().st_size == 69
    line = one_error(*run_cli("features", bomb, "--out", tmp_path / "f.csv")[::2])
    assert "60000 x 60000 px" in line and "100 Mpx" in line and str(bomb) in line
    assert not (tmp_path / "f.csv").exists()


def test_a_real_large_image_in_a_small_file_is_refused_before_decoding(run_cli, tmp_path, no_decoding):
    big = tmp_path / "big.png"
    big.write_bytes(real_gray_png(10_001, 10_000))  # 100.01 Mpx, about 100 kB
    assert big.stat().st_size < 500_000
    line = one_error(*run_cli("features", big, "--out", tmp_path / "f.csv")[::2])
    assert "10001 x 10000 px" in line


def test_the_pixel_limit_is_configurable(run_cli, sandbox, tmp_path):
    image = next((sandbox / "images").iterdir())
    assert one_error(*run_cli("features", image, "--out", tmp_path / "f.csv", "--max-pixels", "1000")[::2])
    code, _, err = run_cli("features", image, "--out", tmp_path / "g.csv", "--max-pixels", str(1920 * 170))
    assert code == 0, err
    text = (sandbox / "study.toml").read_text().replace("[sensor]\n", "[sensor]\nmax_pixels = 300000\n")
    (sandbox / "study.toml").write_text(text)
    line = one_error(*run_cli("features", "--study", sandbox, "--out", tmp_path / "h.csv")[::2])
    assert "above the limit of 0.3 Mpx" in line
    assert run_cli("features", "--study", sandbox, "--out", tmp_path / "i.csv", "--max-pixels", "400000")[0] == 0


def test_a_file_too_large_for_any_image_within_the_limit_is_not_read(run_cli, tmp_path, no_decoding, monkeypatch):
    huge = tmp_path / "huge.png"
    huge.write_bytes(png_claiming(100, 100))
    with huge.open("r+b") as handle:
        handle.truncate(8 * 1000 + (16 << 20) + 1)  # sparse: 16 MB of nothing after a small header
    monkeypatch.setattr(np, "fromfile", lambda *a, **k: pytest.fail("the file was read"))
    line = one_error(*run_cli("features", huge, "--out", tmp_path / "f.csv", "--max-pixels", "1000")[::2])
    assert "more than any image within the pixel limit" in line


@pytest.mark.parametrize("ext", [".png", ".jpg", ".tif", ".bmp"])
@given(width=st.integers(1, 300), height=st.integers(1, 300), colour=st.booleans(), deep=st.booleans())
@settings(max_examples=15)
def test_header_size_matches_the_decoded_image(ext, width, height, colour, deep):
    dtype = np.uint16 if deep and ext in (".png", ".tif") else np.uint8
    pixels = np.zeros((height, width, 3) if colour else (height, width), dtype)
    ok, encoded = cv2.imencode(ext, pixels)
    assert ok
    decoded = cv2.imdecode(encoded, cv2.IMREAD_UNCHANGED)
    assert header_size(encoded) == (decoded.shape[1], decoded.shape[0])


@pytest.mark.parametrize("dtype", [np.float32, np.int16])
def test_header_size_of_a_tiff_pillow_cannot_open(dtype):
    ok, encoded = cv2.imencode(".tif", np.zeros((7, 5, 3), dtype))  # OpenCV reads these; Pillow has no mode for them
    assert ok and cv2.imdecode(encoded, cv2.IMREAD_UNCHANGED).shape == (7, 5, 3)
    assert header_size(encoded) == (5, 7)


@pytest.mark.parametrize("width, height", [(10_000, 10_000), (20_000, 20_000)])  # above Pillow's warning, its refusal
def test_a_huge_header_is_measured_silently_and_pillows_own_limit_is_left_as_it_was(width, height):
    import warnings
    import zlib

    from PIL import Image

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(b"")) + chunk(b"IEND", b""))
    limit = Image.MAX_IMAGE_PIXELS
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # Pillow's DecompressionBombWarning would be an error here
        assert header_size(np.frombuffer(png, np.uint8)) == (width, height)
    assert limit == Image.MAX_IMAGE_PIXELS


def test_bomb_headers_of_every_format_are_refused(tmp_path, no_decoding):
    from roughsense.io.images import check_pixels

    jpeg = b"\xff\xd8\xff\xc0\x00\x11\x08" + struct.pack(">HH", 60000, 60000) + b"\x03" + b"\x00" * 9
    tiff = b"II*\x00\x08\x00\x00\x00" + struct.pack("<H", 2) + struct.pack("<HHII", 256, 4, 1, 60000) \
        + struct.pack("<HHII", 257, 4, 1, 60000) + b"\x00" * 4
    bmp = b"BM" + b"\x00" * 12 + struct.pack("<IiiHH", 40, 60000, -60000, 1, 24) + b"\x00" * 30
    for name, data in (("b.jpg", jpeg), ("b.tif", tiff), ("b.bmp", bmp), ("b.png", png_claiming(60000, 60000))):
        with pytest.raises(InputError, match="60000 x 60000 px"):
            check_pixels(np.frombuffer(data, np.uint8), 100_000_000, tmp_path / name)


# --------------------------------------------------------------------------- 4. the feature cache


def test_a_truncated_cache_entry_is_recomputed(tmp_path, monkeypatch):
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    frame = pd.DataFrame({"image": ["a.png", "b.png"], "specimen": ["R2", "03"], "0.1": [0.25, 1 / 3]})
    calls = []

    def compute():
        calls.append(1)
        return frame

    assert cache.cached_frame("k", compute)[1] is False
    got, hit = cache.cached_frame("k", compute)
    assert hit and len(calls) == 1
    pd.testing.assert_frame_equal(got, frame)
    entry = tmp_path / "cache" / "features" / "k.csv"
    for damage in (lambda b: b[: len(b) // 2], lambda b: b[:-1], lambda b: b.replace(b"0.25", b"0.26"),
                   lambda b: b.split(b"#sha256=")[0]):
        entry.write_bytes(damage(entry.read_bytes()))
        got, hit = cache.cached_frame("k", compute)
        assert not hit
        pd.testing.assert_frame_equal(got, frame)
        assert cache.cached_frame("k", compute)[1]  # repaired


@pytest.mark.slow
def test_study_recomputes_a_truncated_cache_entry_and_an_image_rewritten_in_place(run_cli, sandbox, tmp_path, monkeypatch,
                                                                                   quick_figures):
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    assert run_cli(*study_args(sandbox, tmp_path / "r1"))[0] == 0
    (entry,) = (tmp_path / "cache" / "features").glob("*.csv")
    entry.write_bytes(entry.read_bytes()[: entry.stat().st_size // 3])
    code, out, err = run_cli(*study_args(sandbox, tmp_path / "r2"))
    assert code == 0, err
    html = (tmp_path / "r2" / "index.html").read_text()
    assert "extracted" in html and "from cache" not in html
    assert (tmp_path / "r1" / "results.csv").read_bytes() == (tmp_path / "r2" / "results.csv").read_bytes()
    assert run_cli(*study_args(sandbox, tmp_path / "r3"))[0] == 0
    assert "from cache" in (tmp_path / "r3" / "index.html").read_text()  # the repaired entry is used again

    # An image replaced in place by another's bytes, its mtime set back: not served from the cache.
    images = read_study(sandbox).image_paths
    stat = images[0].stat()
    images[0].write_bytes(images[-1].read_bytes())
    os.utime(images[0], ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert run_cli(*study_args(sandbox, tmp_path / "r4"))[0] == 0
    html = (tmp_path / "r4" / "index.html").read_text()
    assert "extracted" in html and "from cache" not in html
    assert (tmp_path / "r1" / "predictions.csv").read_bytes() != (tmp_path / "r4" / "predictions.csv").read_bytes()


def test_the_features_key_covers_study_toml(sandbox):
    """Issue 28.2: study.toml ([protocol] forces_n labels each image's condition) and the manifest as read are keyed."""
    loaded = read_study(sandbox)
    key = cache.features_key(loaded, {"x": 1})
    toml = sandbox / "study.toml"
    text = toml.read_text()
    assert FORCES_TOML in text
    toml.write_text(text.replace(FORCES_TOML, "forces_n = [1, 2, 3]"))
    assert cache.features_key(read_study(sandbox), {"x": 1}) != key
    toml.write_text(text)
    assert cache.features_key(read_study(sandbox), {"x": 1}) == key
    relabelled = read_study(sandbox)
    relabelled.manifest["condition"] = relabelled.manifest["condition"].replace({"2N": "2.5N"})
    assert cache.features_key(relabelled, {"x": 1}) != key


def test_an_image_rewritten_in_place_with_its_mtime_restored_gets_a_new_key(sandbox):
    loaded = read_study(sandbox)
    key = cache.features_key(loaded, {"x": 1})
    path = loaded.image_paths[0]
    stat = path.stat()
    other = loaded.image_paths[1].read_bytes()
    with path.open("r+b") as handle:  # same inode, same size class: overwrite the bytes in place
        handle.truncate(0)
        handle.write(other)
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert path.stat().st_mtime_ns == stat.st_mtime_ns
    assert cache.features_key(loaded, {"x": 1}) != key


# --------------------------------------------------------------------------- 5. crashes that must be one line


def test_a_header_only_manifest_is_refused_by_study_and_features(run_cli, sandbox, tmp_path):
    manifest = sandbox / "manifest.csv"
    manifest.write_text(manifest.read_text().splitlines()[0] + "\n")
    for args in (study_args(sandbox, tmp_path / "r"), ["features", "--study", sandbox, "--out", tmp_path / "f.csv"],
                 ["fit", "--study", sandbox, "--pad", "smooth", "--condition", "1N", "--out", tmp_path / "m.json"]):
        line = one_error(*run_cli(*args)[::2])
        assert "manifest.csv: lists no images" in line
    assert not (tmp_path / "f.csv").exists()


@pytest.mark.parametrize("file", ["manifest.csv", "specimens.csv", "ratings.csv"])
def test_a_csv_that_is_not_utf8_is_one_line(run_cli, sandbox, tmp_path, file):
    path = sandbox / file
    lines = path.read_text().splitlines()
    lines[2] = lines[2].replace(",", ",\xe9", 1)
    path.write_bytes("\n".join(lines).encode("latin-1") + b"\n")
    line = one_error(*run_cli(*study_args(sandbox, tmp_path / "r"))[::2])
    assert f"{file}, row 3: is not UTF-8 text (byte 0xe9)" in line
    if file == "ratings.csv":  # the same reader behind `roughsense ratings`
        line = one_error(*run_cli("ratings", sandbox / "ratings.csv", "--out", tmp_path / "s.csv")[::2])
        assert f"{file}, row 3: is not UTF-8 text (byte 0xe9)" in line


@pytest.mark.parametrize("table", ["sensor", "study", "protocol"])
def test_a_toml_section_that_is_not_a_table_is_one_line(run_cli, sandbox, tmp_path, table):
    text = (sandbox / "study.toml").read_text()
    start = text.index(f"[{table}]")
    end = text.index("\n[", start + 1)
    (sandbox / "study.toml").write_text(f"{table} = 3\n" + text[:start] + text[end + 1:])
    line = one_error(*run_cli(*study_args(sandbox, tmp_path / "r"))[::2])
    assert f"study.toml: {table} must be a table" in line


def test_a_deeply_nested_toml_is_one_line(run_cli, sandbox, tmp_path):
    with (sandbox / "study.toml").open("a") as handle:
        handle.write("\n[extra]\nx = " + "[" * 3000 + "]" * 3000 + "\n")
    line = one_error(*run_cli(*study_args(sandbox, tmp_path / "r"))[::2])
    assert "nested too deeply" in line


def test_protocol_and_fit_refuse_a_negative_seed(run_cli, sandbox, tmp_path):
    line = one_error(*run_cli("protocol", "--out", tmp_path / "p.csv", "--seed", "-1")[::2])
    assert "--seed must be at least 0, got -1" in line
    line = one_error(*run_cli("fit", "--study", sandbox, "--pad", "smooth", "--condition", "1N", "--out",
                              tmp_path / "m.json", "--cv", "3", "--seed", "-5")[::2])
    assert "--seed" in line
    assert not (tmp_path / "p.csv").exists()


def test_one_participant_left_is_one_line_not_a_numpy_warning(run_cli, sandbox, tmp_path, monkeypatch):
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    ratings = pd.read_csv(sandbox / "ratings.csv", dtype=str)
    ratings[ratings["participant"] == "P01"].to_csv(sandbox / "ratings.csv", index=False)
    line = one_error(*run_cli(*study_args(sandbox, tmp_path / "r"))[::2])
    assert "rated by only 1 participant" in line and "ratings.csv" in line


# --------------------------------------------------------------------------- 6. weak validation


@pytest.mark.parametrize("old, new, message", [
    ('roi = "center"', "roi = [true, 0, 1900, 150]", "not true/false"),
    ("px_per_mm = 34.9", "px_per_mm = true", "px_per_mm must be a positive number"),
    (FORCES_TOML, "forces_n = [true, 2, 3]", "got True"),
    (FORCES_TOML, "forces_n = [1e308, 2, 3]", "up to 100"),
    (FORCES_TOML, 'forces_n = "1,2,3"', "non-empty list of numbers"),
    ('roi = "center"', 'roi = "center"\nmax_pixels = true', "max_pixels must be a whole number of pixels from 1 to"),
    ('name = "simulated"', "name = [1]", "[study] name must be text"),
])
def test_toml_values_of_the_wrong_kind_are_refused(sandbox, old, new, message):
    text = (sandbox / "study.toml").read_text()
    assert old in text
    (sandbox / "study.toml").write_text(text.replace(old, new))
    with pytest.raises(InputError, match=message.replace("[", r"\[")):
        read_study(sandbox)


def test_unknown_toml_keys_warn_once_naming_them_but_the_simulation_table_does_not(run_cli, sandbox, tmp_path):
    assert "[simulation]" in (sandbox / "study.toml").read_text()
    code, _, err = run_cli("features", "--study", sandbox, "--out", tmp_path / "a.csv")
    assert code == 0 and "warning" not in err
    text = (sandbox / "study.toml").read_text().replace('roi = "center"', 'roi = "center"\nroi_typo = [0, 0, 5, 5]')
    (sandbox / "study.toml").write_text(text + "\n[camera]\nmodel = 'x'\n")
    code, _, err = run_cli("features", "--study", sandbox, "--out", tmp_path / "b.csv")
    assert code == 0
    assert [line for line in err.splitlines() if line.startswith("roughsense: warning:")] == [
        f"roughsense: warning: {sandbox / 'study.toml'}: unknown key 'roi_typo' in [sensor] ignored "
        "(known: max_pixels, px_per_mm, roi)",
        f"roughsense: warning: {sandbox / 'study.toml'}: unknown table 'camera' ignored "
        "(known tables: study, sensor, protocol, pads, simulation)",
    ]


def test_a_pads_ridge_period_is_read_from_study_toml(sandbox):
    assert read_study(sandbox).pad_ridge_period_mm == {}  # no [pads] table: every pad is smooth
    text = (sandbox / "study.toml").read_text()
    (sandbox / "study.toml").write_text(text + "\n[pads.smooth]\nridge_period_mm = 0.5\n")
    assert read_study(sandbox).pad_ridge_period_mm == {"smooth": 0.5}


def test_the_simulator_records_the_fingerprint_pads_ridge_period(tmp_path):
    config = SimulationConfig(pads=("smooth", "fingerprint"), specimens=("R3",), repetitions=1, forces_n=(2.0,),
                              participants=2, sessions=1, fingerprint_period_mm=0.8)
    root = simulate_study(tmp_path / "s", with_image_size(config, 1920, 170), jobs=1)
    assert read_study(root).pad_ridge_period_mm == {"fingerprint": 0.8}


@pytest.mark.parametrize("value, message", [
    ("true", "ridge_period_mm must be a number of mm from 0.001 to 100, got True"),
    ("0", "got 0"),
    ("1e-300", "from 0.001 to 100, got 1e-300"),
    ("1e308", "to 100, got 1e+308"),
    ('"1.0"', "got '1.0'"),
])
def test_a_bad_ridge_period_is_one_line_naming_study_toml(run_cli, sandbox, tmp_path, value, message):
    text = (sandbox / "study.toml").read_text()
    (sandbox / "study.toml").write_text(text + f"\n[pads.smooth]\nridge_period_mm = {value}\n")
    code, _, err = run_cli("features", "--study", sandbox, "--out", tmp_path / "a.csv")
    line = one_error(code, err)
    assert message in line and "study.toml" in line and "[pads.smooth]" in line


@pytest.mark.parametrize("column, value, message", [
    ("repetition", "99999999999999999999999", "must be at most 10000"),
    ("repetition", "-1", "must be at least 0, got -1"),
    ("repetition", "1_0", r"not a number: '1_0' \(no '_' between digits: write 10\)"),
    ("force_n", "1e308", "must be at most 100"),
    ("force_n", "true", "not a number: 'true'"),
    ("force_n", "1_0", "not a number: '1_0'"),
    ("force_n", "\u0661", "not a number: '\u0661' \\(write the digits 0-9\\)"),
    ("force_n", "Infinity", "not a finite number: 'Infinity'"),
    ("contact_fraction", "1e308", "must be at most 1, got 1e"),
])
def test_manifest_numbers_out_of_range_are_refused_by_cell(sandbox, column, value, message):
    edit_csv(sandbox / "manifest.csv", 6, column, value)
    with pytest.raises(InputError, match=message) as caught:
        read_study(sandbox)
    assert (caught.value.row, caught.value.column) == (6, column)


def test_option_forces_and_repetitions_are_bounded(run_cli, tmp_path):
    line = one_error(*run_cli("simulate", "--out", tmp_path / "s", "--forces-n", "1,1e308")[::2])
    assert "up to 100" in line
    line = one_error(*run_cli("simulate", "--out", tmp_path / "s", "--repetitions", "100000000000")[::2])
    assert "from 1 to 10000" in line
    assert not (tmp_path / "s").exists()


@pytest.fixture(scope="module")
def model_document(base, tmp_path_factory):
    from roughsense.cli import main

    path = tmp_path_factory.mktemp("model") / "m.json"
    assert main(["fit", "--model", "pls", "--study", str(base), "--pad", "smooth", "--condition", "2N", "--out", str(path)]) == 0
    return json.loads(path.read_text())


def _resigned(document: dict) -> dict:
    from roughsense.model.modelfile import _digest

    document = json.loads(json.dumps(document))
    document["sha256"] = _digest(document)
    return document


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.update(version=1.0), "version 1.0 is not supported"),
    (lambda d: d.update(version=True), "version True is not supported"),
    (lambda d: d["model"].update(coefficients=[[str(v) for v in row] for row in d["model"]["coefficients"]]),
     "model.coefficients must be an array of numbers"),
    (lambda d: d["model"].update(intercepts=[True] * len(d["model"]["intercepts"])),
     "model.intercepts must be an array of numbers"),
])
def test_model_files_with_wrong_kinds_are_refused_even_with_a_valid_checksum(run_cli, base, model_document, tmp_path,
                                                                             edit, message):
    document = json.loads(json.dumps(model_document))
    edit(document)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(_resigned(document)))
    image = next((base / "images").iterdir())
    line = one_error(*run_cli("predict", path, image)[::2])
    assert message in line


def test_a_model_file_over_10_mb_is_refused_without_reading_it(run_cli, base, tmp_path, monkeypatch):
    path = tmp_path / "huge.json"
    with path.open("wb") as handle:
        handle.truncate(11_000_000)  # sparse: costs no disk
    reads = []
    real_loads = json.loads
    monkeypatch.setattr(json, "loads", lambda *a, **k: reads.append(1) or real_loads(*a, **k))
    line = one_error(*run_cli("predict", path, next((base / "images").iterdir()))[::2])
    assert "larger than 10 MB" in line and not reads


@pytest.mark.slow
def test_a_blank_rating_means_the_same_to_ratings_and_study(run_cli, sandbox, tmp_path, monkeypatch, quick_figures):
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    ratings = pd.read_csv(sandbox / "ratings.csv", dtype=str, keep_default_na=False)
    ratings.loc[0, "rating"] = ""
    ratings.to_csv(sandbox / "ratings.csv", index=False)
    blank = ratings.loc[0]
    code, _, err = run_cli("ratings", sandbox / "ratings.csv", "--out", tmp_path / "s.csv")
    assert code == 0
    gap = f"participant {blank['participant']}, session {blank['session']}: no rating for {blank['specimen']}"
    assert gap in err
    code, _, err = run_cli(*study_args(sandbox, tmp_path / "r"))
    assert code == 0, err
    assert gap in err
    summary = pd.read_csv(tmp_path / "s.csv", dtype={"specimen": str}).set_index("specimen")
    report = read_study(sandbox).ratings
    assert len(report) == len(ratings) - 1
    kept = ratings.iloc[1:].astype({"rating": float})
    expected = kept[kept["specimen"] == blank["specimen"]].groupby("participant")["rating"].median()
    assert summary.loc[blank["specimen"], "gmean"] == pytest.approx(float(np.exp(np.log(expected).mean())))


@given(st.text(alphabet=st.characters(exclude_categories=("Cs",)), max_size=30))
@settings(max_examples=200)
def test_study_toml_strings_round_trip_whatever_they_hold(text):
    """The writer's TOML escapes quotes, backslashes and control characters (a folder name may hold any)."""
    import tomllib

    assert tomllib.loads(dump_toml({"study": {"name": text}}))["study"]["name"] == text


def test_a_non_default_pixel_limit_is_written_to_study_toml(tmp_path):
    writer = StudyWriter(tmp_path / "s")
    writer.write_config(name="s", sensor=SensorSettings(max_pixels=5000))
    assert read_config(tmp_path / "s" / "study.toml")["sensor"]["max_pixels"] == 5000


@pytest.mark.parametrize("text, message", [
    ("[sweep]\nx = " + "[" * 3000 + "]" * 3000 + "\n", "nested too deeply"),
    ("[sweep]\nimage_size_px = [200000, 200000]\n[axes]\n", "above the limit of 100 Mpx per frame"),
])
def test_a_hostile_sweep_file_is_one_line(run_cli, tmp_path, text, message):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(text)
    line = one_error(*run_cli("explore", sweep, "--out", tmp_path / "out")[::2])
    assert message in line and not (tmp_path / "out").exists()


# --------------------------------------------------------------------------- 7. European Excel (issue 21, item 2)


def test_a_simulated_study_saved_by_european_excel_reads_the_same(sandbox, tmp_path):
    """BOM, ';' between cells, decimal commas and CRLF in all three CSVs: the same study, one warning per file."""
    import warnings

    from roughsense.errors import RoughsenseWarning

    reference = read_study(sandbox)
    euro = shutil.copytree(sandbox, tmp_path / "euro")
    for name in ("specimens.csv", "manifest.csv", "ratings.csv"):
        frame = pd.read_csv(euro / name, dtype=str, keep_default_na=False)
        names = {"image", "specimen", "pad", "participant", "session", "shape"}
        for column in set(frame.columns) - names:
            frame[column] = frame[column].str.replace(".", ",", regex=False)
        text = frame.to_csv(index=False, sep=";", lineterminator="\r\n")
        assert "," in text or name == "specimens.csv"
        (euro / name).write_bytes("\ufeff".encode() + text.encode())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        study = read_study(euro)
    assert sorted(str(w.message).split(": ", 1)[1] for w in caught if issubclass(w.category, RoughsenseWarning)) == [
        "read as semicolon-separated with decimal commas (as European Excel saves it)"] * 3
    for ours, theirs in ((study.specimens, reference.specimens), (study.manifest, reference.manifest),
                         (study.ratings, reference.ratings)):
        pd.testing.assert_frame_equal(ours, theirs)
    assert study.manifest["force_n"].between(0.5, 3.5).all() and not study.manifest["force_n"].eq(0).any()


def test_the_issue_examples_now_say_what_to_do(run_cli, sandbox, tmp_path):
    """The two messages quoted in issue 21 (a semicolon header mixed with commas; a decimal comma in a comma file)."""
    (sandbox / "specimens.csv").write_bytes("\ufeffspecimen;shape;wavelength_mm,x\nR2;rectangular;2,1\n".encode())
    line = one_error(*run_cli(*study_args(sandbox, tmp_path / "r"))[::2])
    assert "found specimen;shape;wavelength_mm, x; the header mixes ',' and ';' separators" in line
    assert "CSV UTF-8 (comma delimited)" in line
    (sandbox / "specimens.csv").write_bytes("\ufeffspecimen,shape,wavelength_mm\nR2,rectangular,0,5\n".encode())
    line = study_error(run_cli, sandbox, tmp_path / "r")
    assert line.endswith("row 2: 4 fields but the header has 3 (extra value '5'); a decimal comma? "
                         "write numbers with a point (0.5, not 0,5)")


# --------------------------------------------------------------------------- issue 22: one number parser, bounded


@pytest.mark.parametrize("cell, message", [
    ("1_0", "not a number: '1_0' (no '_' between digits: write 10)"),
    ("\u0661", "not a number: '\u0661' (write the digits 0-9)"),
    ("1e308", "a magnitude estimate must be at most 1e+06, got 1e+308"),
])
def test_a_rating_cell_means_the_same_to_study_and_ratings(run_cli, sandbox, tmp_path, cell, message):
    """Item 4/5: study read '1_0' as 10 while ratings refused it; 1e308 gave sd = inf. One parser, one line each."""
    edit_csv(sandbox / "ratings.csv", 4, "rating", cell)
    where = f"{sandbox / 'ratings.csv'}, row 4, column 'rating': "
    by_study = study_error(run_cli, sandbox, tmp_path / "report")
    by_ratings = one_error(*run_cli("ratings", sandbox / "ratings.csv", "--out", tmp_path / "summary.csv")[::2])
    assert by_study == by_ratings == f"roughsense: error: {where}{message}"
    assert not (tmp_path / "report").exists() and not (tmp_path / "summary.csv").exists()


def test_ratings_at_the_bounds_give_finite_statistics(run_cli, tmp_path):
    path = tmp_path / "ratings.csv"
    path.write_text("participant,session,specimen,rating\nP1,1,R2,1e6\nP2,1,R2,1e-6\nP3,1,R2,1e6\n")
    code, _, err = run_cli("ratings", path, "--out", tmp_path / "s.csv")
    assert code == 0, err
    summary = pd.read_csv(tmp_path / "s.csv").set_index("specimen")
    assert np.isfinite(summary.loc["R2", ["gmean", "sd"]].astype(float)).all()
    assert summary.loc["R2", "gmean"] == pytest.approx(1e2)  # (1e6 * 1e-6 * 1e6) ** (1/3)


@pytest.mark.parametrize("old, new, message", [
    ("px_per_mm = 34.9", "px_per_mm = 1e-9", "[sensor] px_per_mm must be at least 0.01, got 1e-09"),
    ("px_per_mm = 34.9", "px_per_mm = 1e300", "[sensor] px_per_mm must be at most 100000, got 1e+300"),
    ('roi = "center"', 'roi = "1_0,0,1900,150"', "ROI must be 'center', 'auto' or X,Y,W,H with whole numbers"),
])
def test_study_toml_numbers_are_bounded_and_spelled_as_in_a_csv(run_cli, sandbox, tmp_path, old, new, message):
    text = (sandbox / "study.toml").read_text()
    assert old in text
    (sandbox / "study.toml").write_text(text.replace(old, new))
    line = one_error(*run_cli("features", "--study", sandbox, "--out", tmp_path / "f.csv")[::2])
    assert message in line and "study.toml" in line


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["model"]["coefficients"][-1].__setitem__(0, 1e308),
     "model.coefficients holds 1e+308; a fitted model's are at most 1e+06 in magnitude"),
    (lambda d: d["model"]["intercepts"].__setitem__(-1, 1e300), "model.intercepts["),
    (lambda d: d["model"].update(y_mean=1e300), "model.y_mean is 1e+300; a rating is at most 1e+06"),
    (lambda d: d["model"]["x_mean"].__setitem__(0, -1e200), "model.x_mean holds 1e+200"),
    # Issue 28.10: a re-signed file with 200,000 frequencies made predict reach 24 GB.
    (lambda d: d["features"]["spectrum"].update(n_freqs=200_000), "spectrum has n_freqs 200000; at most 5000"),
])
def test_a_resigned_model_file_with_extreme_numbers_is_refused(run_cli, base, model_document, tmp_path, edit, message):
    """Item 5: the checksum is unkeyed, so 1e308 coefficients re-signed made predict write inf with exit 0."""
    document = json.loads(json.dumps(model_document))
    edit(document)
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(_resigned(document)))
    line = one_error(*run_cli("predict", path, next((base / "images").iterdir()), "--out", tmp_path / "p.csv")[::2])
    assert message in line and str(path) in line
    assert not (tmp_path / "p.csv").exists()


def test_a_fitted_model_is_far_inside_the_model_file_bounds(model_document):
    from roughsense.model.pls.file import MAX_COEFFICIENT, MAX_X_MEAN

    model = model_document["model"]
    assert np.abs(model["coefficients"]).max() < MAX_COEFFICIENT / 1000
    assert np.abs(model["x_mean"]).max() < MAX_X_MEAN / 1000
    x_mean, coef = np.array(model["x_mean"]), np.array(model["coefficients"])
    np.testing.assert_allclose(model["intercepts"], model["y_mean"] - coef @ x_mean, rtol=1e-9, atol=1e-12)



def test_a_synthetic_declaration_must_say_where_the_images_came_from(tmp_path):
    """Issue 30: [study] synthetic marks a folder of synthetic images (the shipped example); it must be text."""
    from roughsense.errors import InputError
    from roughsense.io.study import _read_settings
    from roughsense.io.study_config import read_config

    (tmp_path / "study.toml").write_text('[study]\nsynthetic = 1\n')
    assert read_config(tmp_path / "study.toml")["study"]["synthetic"] == 1
    with pytest.raises(InputError, match=r"\[study\] synthetic must say, as text"):
        _read_settings(tmp_path, None)
