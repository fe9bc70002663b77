"""``roughsense features`` at the command line: CSV contract, study folders and every bad input."""
from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest

from roughsense.cli.features import unit_names
from roughsense.io.sensor_settings import SensorSettings
from roughsense.io.writer import StudyWriter
from roughsense.sensor.contact_geometry import CONTACT_MEASURES
from roughsense.sensor.grid import frequency_grid
from roughsense.sensor.line import spatial_spectrum
from roughsense.sensor.spectrum import SpatialSpectrum
from tests.commands import error_line, grating_png

PX_PER_MM = 34.9


def grating_frame(wavelength_mm, width_px=1920, height_px=1080, px_per_mm=PX_PER_MM):
    x_mm = np.arange(width_px) / px_per_mm
    line = 0.5 + 0.35 * np.tanh(3 * np.sin(2 * np.pi * x_mm / wavelength_mm))
    return np.tile(np.round(255 * line).astype(np.uint8), (height_px, 1))


def write_png(path: Path, pixels) -> Path:
    assert cv2.imwrite(str(path), pixels)
    return path


@pytest.fixture
def images(tmp_path):
    return [write_png(tmp_path / f"grating_{w}mm.png", grating_frame(w)) for w in (2.0, 3.0, 5.0)]


def test_features_csv_has_image_column_and_round_tripping_grid(run_cli, tmp_path, images):
    out = tmp_path / "features.csv"
    code, stdout, err = run_cli("features", *images, "--out", out, "--jobs", "2")
    assert code == 0, err
    table = pd.read_csv(out)
    assert list(table.columns[:1]) == ["image"] and len(table.columns) == 46 + len(CONTACT_MEASURES)
    assert list(table.columns[46:]) == list(CONTACT_MEASURES)
    assert table.columns[1] == "f_0.1000_per_mm" and table.columns[2] == "f_0.1205_per_mm"  # the unit in the header
    definition = json.loads((tmp_path / "features.spectrum.json").read_text())  # the grid, exact, stored once
    headers = np.array(definition["freq_per_mm"])
    np.testing.assert_array_equal(headers, frequency_grid())
    assert [f"f_{f:.4f}_per_mm" for f in headers] == list(table.columns[1:46])
    assert SpatialSpectrum.from_definition(definition).feature_definition() == definition
    assert list(table["image"]) == [str(p) for p in images]
    for path, row in zip(images, table.iloc[:, 1:46].to_numpy()):
        np.testing.assert_allclose(row, spatial_spectrum(path), rtol=1e-12)
    peaks = headers[table.iloc[:, 1:46].to_numpy().argmax(axis=1)]
    np.testing.assert_allclose(peaks, [0.5, 1 / 3, 0.2], atol=(0.9 / 44) / 2 + 1e-12)


def test_features_options_reach_the_library(run_cli, tmp_path, images):
    out = tmp_path / "f.csv"
    args = ["--px-per-mm", "30", "--roi", "5,400,1800,120", "--rows", "7", "--band", "0.15,0.9", "--n-freqs", "20",
            "--window", "none"]
    code, _, err = run_cli("features", images[1], "--out", out, *args)
    assert code == 0, err
    table = pd.read_csv(out)
    grid = json.loads((tmp_path / "f.spectrum.json").read_text())["freq_per_mm"]
    np.testing.assert_array_equal(grid, frequency_grid(0.15, 0.9, 20))
    assert len(table.columns) == 21 + len(CONTACT_MEASURES)
    assert all(c.startswith("f_") and c.endswith("_per_mm") for c in table.columns[1:21])
    expected = spatial_spectrum(
        images[1], px_per_mm=30, roi=(5, 400, 1800, 120), rows=7, f_min_per_mm=0.15, f_max_per_mm=0.9, n_freqs=20, window="none"
    )
    np.testing.assert_allclose(table.iloc[0, 1:21].to_numpy(float), expected, rtol=1e-12)


def _study(root: Path, px_per_mm: float) -> Path:
    writer = StudyWriter(root)
    writer.write_config(name="tiny", sensor=SensorSettings(px_per_mm=px_per_mm, roi="auto"))
    writer.write_specimens(pd.DataFrame({"specimen": ["R2", "R3"], "shape": ["rectangular"] * 2, "wavelength_mm": [2.0, 3.0]}))
    rows = []
    for specimen, wavelength_mm in (("R2", 2.0), ("R3", 3.0)):
        for force_n in (1.0, 2.0):
            name = writer.write_image(f"{specimen}_{force_n:g}N.png", grating_frame(wavelength_mm, 800, 300, px_per_mm))
            rows.append({"image": name, "specimen": specimen, "pad": "A", "force_n": force_n + 0.02, "repetition": 1})
    writer.write_manifest(pd.DataFrame(rows))
    return root


def test_features_for_a_study_carry_the_manifest_and_use_its_sensor_settings(run_cli, tmp_path):
    study = _study(tmp_path / "study", px_per_mm=20.0)
    out = tmp_path / "features.csv"
    code, _, err = run_cli("features", "--study", study, "--out", out)
    assert code == 0, err
    table = pd.read_csv(out)
    manifest = pd.read_csv(study / "manifest.csv")
    assert list(table.columns[:5]) == list(manifest.columns)
    pd.testing.assert_frame_equal(table[manifest.columns], manifest)
    assert list(table["condition"]) == ["1N", "2N", "1N", "2N"]
    features = table[[c for c in table.columns if c.startswith("f_")]].to_numpy(float)
    for rel, row in zip(table["image"], features):
        np.testing.assert_allclose(row, spatial_spectrum(study / rel, px_per_mm=20.0, roi="auto"), rtol=1e-12)
    # an explicit option overrides the study's setting
    code, _, err = run_cli("features", "--study", study, "--out", out, "--force", "--px-per-mm", "25")
    assert code == 0, err
    row = pd.read_csv(out).iloc[0][[c for c in table.columns if c.startswith("f_")]].to_numpy(float)
    np.testing.assert_allclose(row, spatial_spectrum(study / table["image"][0], px_per_mm=25.0, roi="auto"), rtol=1e-12)


def _assert_clean_failure(result, out: Path, *names: str):
    code, stdout, err = result
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("roughsense: error: "), err
    assert "Traceback" not in err
    for name in names:
        assert name in lines[0]
    assert not out.exists()
    assert not list(out.parent.glob(f".{out.name}.*"))  # no temporary left behind


@pytest.mark.parametrize(
    "case",
    ["corrupt", "truncated", "empty", "missing", "small", "roi-outside", "short-line", "rows"],
)
def test_bad_image_in_a_batch_names_the_file_and_writes_nothing(run_cli, tmp_path, images, case):
    bad = tmp_path / f"bad_{case}.png"
    extra: list[str] = []
    if case == "corrupt":
        bad.write_bytes(b"\x89PNG\r\n\x1a\n" + b"garbage" * 50)
    elif case == "truncated":
        data = images[0].read_bytes()
        bad.write_bytes(data[: len(data) // 2])
    elif case == "empty":
        bad.write_bytes(b"")
    elif case == "small":
        write_png(bad, grating_frame(3.0, 1280, 720)[:100])
    elif case == "roi-outside":
        write_png(bad, grating_frame(3.0, 1920, 400))
        extra = ["--roi", "0,300,1900,150"]
    elif case == "short-line":
        write_png(bad, grating_frame(3.0, 300, 200))
        extra = ["--roi", "auto"]
    elif case == "rows":  # the auto crop is only as tall as the image
        write_png(bad, grating_frame(3.0, 1920, 100))
        extra = ["--roi", "auto", "--rows", "120"]
    out = tmp_path / "features.csv"
    result = run_cli("features", images[0], bad, images[1], "--out", out, "--jobs", "2", *extra)
    _assert_clean_failure(result, out, bad.name)


@pytest.mark.parametrize("value", ["0", "-34.9", "nan"])
def test_px_per_mm_must_be_positive(run_cli, tmp_path, images, value):
    out = tmp_path / "features.csv"
    _assert_clean_failure(run_cli("features", images[0], "--out", out, f"--px-per-mm={value}"), out,
                          "--px-per-mm must be a positive number")


@pytest.mark.parametrize("args, words", [
    (["--band", "1.0,0.1"], ["band"]), (["--band", "0.1"], ["--band"]), (["--roi", "1,2,3"], ["ROI"]),
    (["--n-freqs", "1"], ["--n-freqs must be at least 2"]), (["--rows", "151"], ["rows 151", "150 px"]),
    (["--roi", "0,0,1900,20", "--rows", "21"], ["rows 21"]),
])
def test_bad_options_fail_cleanly(run_cli, tmp_path, images, args, words):
    out = tmp_path / "features.csv"
    _assert_clean_failure(run_cli("features", images[0], "--out", out, *args), out, *words)


def test_existing_output_needs_force(run_cli, tmp_path, images):
    out = tmp_path / "features.csv"
    out.write_text("mine\n")
    code, _, err = run_cli("features", images[0], "--out", out)
    assert code == 2 and str(out) in err and "--force" in err
    assert out.read_text() == "mine\n"
    code, _, err = run_cli("features", images[0], "--out", out, "--force")
    assert code == 0, err
    assert pd.read_csv(out).shape == (1, 46 + len(CONTACT_MEASURES))


def test_images_and_study_are_exclusive_and_one_is_needed(run_cli, tmp_path, images):
    out = tmp_path / "features.csv"
    _assert_clean_failure(run_cli("features", images[0], "--study", tmp_path, "--out", out), out, "--study")
    _assert_clean_failure(run_cli("features", "--out", out), out, "IMAGE")


def test_study_with_a_broken_image_names_it(run_cli, tmp_path):
    study = _study(tmp_path / "study", px_per_mm=20.0)
    broken = study / "images" / "R3_2N.png"
    broken.write_bytes(broken.read_bytes()[:200])
    out = tmp_path / "features.csv"
    _assert_clean_failure(run_cli("features", "--study", study, "--out", out), out, "R3_2N.png")


def test_help_documents_the_options(run_cli):
    code, stdout, _ = run_cli("features", "--help")
    assert code == 0
    for option in ("--px-per-mm", "--roi", "--rows", "--band", "--n-freqs", "--jobs", "--study", "--out", "--force"):
        assert option in stdout


@pytest.mark.parametrize("extra", [[], ["--roi", "auto"]])
@pytest.mark.parametrize("where", [0.3, 0.5, 0.9])
def test_png_with_damaged_image_data_is_refused_whatever_rows_are_read(tmp_path, images, capfd, extra, where):
    """A PNG whose chunk structure is intact but whose compressed data is damaged: one line, even from libpng."""
    from roughsense.cli import main

    data = bytearray(images[0].read_bytes())
    middle = int(len(data) * where)
    data[middle : middle + 64] = bytes(b ^ 0x5A for b in data[middle : middle + 64])
    bad = tmp_path / "damaged.png"
    bad.write_bytes(bytes(data))
    out = tmp_path / "features.csv"
    code = main(["features", str(bad), "--out", str(out), *extra])
    captured = capfd.readouterr()  # file-descriptor level: a codec printing to stderr would show here
    assert code == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "damaged.png" in lines[0] and "CRC" in lines[0], captured.err
    assert not out.exists()


@pytest.mark.parametrize("roi", ["nan,0,10,10", "0,inf,10,10", "1e400,0,5,5"])
def test_non_finite_roi_is_a_clean_error(run_cli, tmp_path, images, roi):
    out = tmp_path / "features.csv"
    _assert_clean_failure(run_cli("features", images[0], "--out", out, f"--roi={roi}"), out, "ROI")


def test_unit_names_keep_every_frequency_distinct():
    assert unit_names([0.1, 0.12045454545]) == ["f_0.1000_per_mm", "f_0.1205_per_mm"]
    fine = frequency_grid(0.1, 0.1001, 5)  # closer than 4 decimals tell apart
    assert len(set(unit_names(fine))) == 5


def test_features_refuses_to_replace_a_definition_file_without_force(run_cli, tmp_path, images):
    (tmp_path / "f.spectrum.json").write_text("mine")
    code, _, err = run_cli("features", images[0], "--out", tmp_path / "f.csv")
    assert code == 2 and "f.spectrum.json" in err and "--force" in err and err.count("\n") == 1
    assert not (tmp_path / "f.csv").exists() and (tmp_path / "f.spectrum.json").read_text() == "mine"


def test_plot_draws_one_images_line_and_spectrum(run_cli, tmp_path, images):
    """--plot: the contact line and the spectrum with its peak marked, in the format the file name says."""
    import matplotlib.pyplot as plt

    from roughsense.report import figures
    from roughsense.sensor.spectrum import SpatialSpectrum

    code, stdout, err = run_cli("features", images[1], "--out", tmp_path / "f.csv", "--plot", tmp_path / "one.svg")
    assert code == 0, err
    svg = (tmp_path / "one.svg").read_text()
    assert svg.startswith("<?xml") and "peak 0.325" in svg and "one.svg" in stdout
    line, box = SpatialSpectrum().fit().line(images[1])
    assert box == (10, 465, 1900, 150) and line.shape == (1900,)
    spectrum = spatial_spectrum(images[1])
    fig = figures.line_spectrum_figure(line, 34.9, frequency_grid(), spectrum, "t")
    marked = fig.axes[1].lines[1]
    assert marked.get_xdata()[0] == frequency_grid()[spectrum.argmax()]
    plt.close(fig)
    for bad, needle in ((["--plot", tmp_path / "p.png", images[0], images[1]], "exactly one IMAGE"),
                        (["--plot", tmp_path / "p.jpg", images[0]], "must end in .png, .svg or .pdf")):
        code, _, err = run_cli("features", "--out", tmp_path / "g.csv", *bad)
        assert code == 2 and needle in err and err.count("\n") == 1 and not (tmp_path / "g.csv").exists()


@pytest.mark.parametrize("plot_is", ["the image", "--out"])
def test_features_plot_never_replaces_an_input_or_another_output(run_cli, tmp_path, plot_is):
    """36.2: ``features in.png -o x.csv --force --plot in.png`` replaced the image with the plot."""
    image = grating_png(tmp_path / "in.png")
    before = image.read_bytes()
    plot = {"the image": image, "--out": tmp_path / "x.png"}[plot_is]
    out = tmp_path / ("x.png" if plot_is == "--out" else "x.csv")
    code, _, err = run_cli("features", image, "-o", out, "--force", "--plot", plot)
    assert code == 2 and "--plot" in error_line(err) and "choose another path" in err
    assert image.read_bytes() == before and not out.exists()


def test_a_stop_while_features_draws_its_plot_leaves_no_csv_behind(run_cli, tmp_path, monkeypatch):
    """36.5's "never commits after it" for a run of several outputs: features wrote its CSV and grid file, then drew
    --plot, so a SIGTERM (or a failure) while drawing left the CSV without the plot it was asked for."""
    import signal

    from roughsense._util import interrupt
    from roughsense.report import figures
    from tests.commands import grating_png

    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    interrupt.install()
    real = figures.figure_bytes

    def signalled(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)  # arrives while the figure is drawn
        return real(*args, **kwargs)

    monkeypatch.setattr(figures, "figure_bytes", signalled)
    image = grating_png(tmp_path / "in.png")
    try:
        code, _, err = run_cli("features", image, "-o", tmp_path / "x.csv", "--plot", tmp_path / "plot.png")
    finally:
        for number, handler in saved.items():
            signal.signal(number, handler)
        interrupt._received.clear()
    assert code == 143 and err == "roughsense: interrupted\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.png"]


def test_features_write_the_contact_measures_and_draw_them(run_cli, tmp_path, images):
    """Issue 46: land and groove widths (bare names, units in them) for IMAGE..., read as on a smooth pad unless
    --ridge-period-mm names the pad's ridges; the --plot figure shows the band with the widths written; the option
    is refused with --study (a study's pads carry their own) and outside its bounds, one line each."""
    out = tmp_path / "f.csv"
    code, stdout, err = run_cli("features", *images, "--out", out, "--jobs", "1")
    assert code == 0, err
    assert "4 contact measures" in stdout
    table = pd.read_csv(out)
    spectrum = SpatialSpectrum().fit()
    expected = np.vstack([c for _, c in spectrum.iter_transform_contact(images)])
    np.testing.assert_allclose(table[list(CONTACT_MEASURES)].to_numpy(float), expected, rtol=1e-12)
    # the frames' lands are half of each period (tanh of a sine): land = groove = period / 2 within 0.05 mm
    np.testing.assert_allclose(table["land_mm"], [1.0, 1.5, 2.5], atol=0.05)
    np.testing.assert_allclose(table["groove_mm"], [1.0, 1.5, 2.5], atol=0.05)
    code, _, err = run_cli("features", images[1], "--out", out, "--force", "--ridge-period-mm", "0.7",
                           "--plot", tmp_path / "one.svg")
    assert code == 0, err
    ridged = np.vstack([c for _, c in spectrum.iter_transform_contact([images[1]], ridge_period_mm=0.7)])
    np.testing.assert_allclose(pd.read_csv(out)[list(CONTACT_MEASURES)].to_numpy(float), ridged, rtol=1e-12)
    assert "groove (gap, red)" in (tmp_path / "one.svg").read_text()
    for bad, needle in ((["--study", tmp_path, "--ridge-period-mm", "1"], "--ridge-period-mm is for IMAGE"),
                        ([images[0], "--ridge-period-mm", "0"], "--ridge-period-mm must be")):
        code, _, err = run_cli("features", "--out", tmp_path / "g.csv", *bad)
        assert code == 2 and needle in err and err.count("\n") == 1 and not (tmp_path / "g.csv").exists()
