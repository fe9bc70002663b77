"""Specimens, pads and camera of the twin: the paper's geometry and the spec syntax for new parts."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from roughsense.errors import ConfigError
from roughsense.paper import PAPER_SPECIMENS
from roughsense.sim.optics import Camera, Lighting, render
from roughsense.sim.pads import make_pad
from roughsense.sim.specimens import PRESETS, parse_specimen
from tests.commands import one_error
from tests.fuzzing import EXAMPLES, FUZZ, NUMBER_CHARS
from tests.sweeps import SWEEP


def test_paper_presets():
    assert PAPER_SPECIMENS == ("R2", "R2.5", "R3", "R3.5", "R4", "R4.5", "R5",
                               "C2", "C2.5", "C3", "C3.5", "C4", "C4.5", "C5")
    assert PRESETS["R3.5"].wavelength_mm == 3.5 and PRESETS["R3.5"].ridge_width_mm == 1.75
    assert PRESETS["R3.5"].groove_depth_mm == 1.0  # our choice (not in the paper; docs/simulator.md)
    assert PRESETS["C4.5"].diameter_mm == 4.5


@given(st.sampled_from(PAPER_SPECIMENS[:7]))
def test_rectangular_grating_has_equal_ridges_and_grooves(name):
    spec = PRESETS[name]
    x = (np.arange(100000) + 0.5) * (spec.wavelength_mm / 100000)
    h = spec.height_mm(x)
    assert np.mean(h == 0) == pytest.approx(0.5, abs=1e-4)
    assert set(np.unique(h)) == {0.0, -1.0}


@given(st.sampled_from(PAPER_SPECIMENS[7:]), st.floats(0, 1))
def test_circular_grating_is_touching_semicylinders(name, t):
    spec = PRESETS[name]
    radius = spec.wavelength_mm / 2
    x = t * spec.wavelength_mm
    expected = math.sqrt(max(radius**2 - (x - radius) ** 2, 0.0)) - radius
    assert float(spec.height_mm(np.array([x]))[0]) == pytest.approx(expected, abs=1e-12)
    assert float(spec.height_mm(np.array([0.0]))[0]) == pytest.approx(-radius)  # cylinders touch at their feet


def test_specimen_specs():
    sin = parse_specimen("sin:3.0:0.5")
    assert (sin.shape, sin.wavelength_mm, sin.amplitude_mm) == ("sinusoidal", 3.0, 0.5)
    x = np.linspace(0, 3, 301)
    assert np.ptp(sin.height_mm(x)) == pytest.approx(1.0)  # peak to peak = 2 x amplitude
    rect = parse_specimen("rect:3.5")
    assert (rect.ridge_width_mm, rect.groove_depth_mm) == (1.75, 1.0)
    assert parse_specimen("rect:4:0.5:1").groove_width_mm == 3.0
    assert parse_specimen("circ:2.5").diameter_mm == 2.5
    rand = parse_specimen("rand:1.5:0.2:7")
    h = rand.height_mm(np.linspace(0, 50, 4001)[:-1])
    assert h.std() == pytest.approx(0.2, rel=0.02) and h.max() == pytest.approx(0.0, abs=1e-3)
    assert parse_specimen("c3") == PRESETS["C3"]


@pytest.mark.parametrize("text", ["R7", "rect:0", "rect:-2", "sin:3", "circ:abc", "hex:3", "rect:3:1:3", "sin:3:0"])
def test_bad_specimen_specs(text):
    with pytest.raises(ConfigError):
        parse_specimen(text)


def test_fingerprint_pad_relief():
    pad = make_pad("fingerprint")
    n, length = 8000, 20.0
    x = np.arange(n) * (length / n)
    h = pad.height_mm(x)
    assert h.max() == pytest.approx(0.0, abs=1e-6) and h.min() == pytest.approx(-0.2, abs=1e-6)
    assert np.mean(h > -0.1) == pytest.approx(0.5, abs=1e-3)  # 0.5 mm ridges, 0.5 mm grooves
    amplitude = np.abs(np.fft.rfft(h - h.mean()))
    freq = np.fft.rfftfreq(n, d=length / n)
    assert freq[np.argmax(amplitude)] == pytest.approx(1.0)  # a peak at 1 mm^-1 along the line
    assert make_pad("fingerprint", fingerprint_period_mm=0.5).period_mm == 0.5
    assert not make_pad("smooth").has_ridges
    with pytest.raises(ConfigError):
        make_pad("velvet")
    with pytest.raises(ConfigError):
        make_pad("fingerprint", fingerprint_period_mm=0.0)


def test_default_camera_geometry():
    cam = Camera()
    assert (cam.width_px, cam.height_px, cam.px_per_mm) == (1920, 1080, 34.9)
    assert cam.field_mm == pytest.approx(55.0, abs=0.05)  # 5.5 cm x 3.1 cm (paper section 2.1)
    assert cam.height_px / cam.px_per_mm == pytest.approx(31.0, abs=0.1)
    assert cam.band_height_px == pytest.approx(10 * math.cos(math.radians(45)) * 34.9)
    assert cam.contrast(np.array([0.0]))[0] == pytest.approx(1.0)
    assert cam.contrast(np.array([1.0]))[0] < 0.01


def test_render_puts_the_band_in_the_middle_and_quantises():
    cam = Camera(width_px=400, height_px=600, read_noise_dn=0.0, shot_noise_gain=0.0, vignetting=0.0,
                 blur_sigma_px=0.0, stored_height_px=0)
    line = np.zeros(400)
    line[100:200] = 1.0
    frame = render(cam, line, band_center_px=300.0, lighting=Lighting(), rng=np.random.default_rng(0))
    assert frame.dtype == np.uint8 and frame.shape == (600, 400)
    assert frame[300, 150] == round(cam.contact_dn) and frame[300, 50] == round(cam.band_floor_dn)
    assert frame[10, 150] == round(cam.background_dn)


@pytest.mark.parametrize("correlation_mm", [0.5, 1.0])
def test_random_grating_has_the_stated_gaussian_autocorrelation(correlation_mm):
    # exp(-(x/l)^2): e^-1 at lag l, e^-4 at lag 2l. 50 mm holds 50-100 correlation lengths; 40 profiles more.
    n = 4096
    step = 50.0 / n
    acf = np.zeros(n)
    for seed in range(40):
        h = parse_specimen(f"rand:{correlation_mm:g}:0.1:{seed}").height_mm(np.arange(n) * step)
        h = h - h.mean()
        acf += np.fft.irfft(np.abs(np.fft.rfft(h)) ** 2, n)  # circular: the profile is periodic over the specimen
    acf /= acf[0]
    lag = np.arange(n) * step

    def at(x):
        return float(np.interp(x, lag, acf))

    assert at(correlation_mm) == pytest.approx(math.exp(-1), abs=0.04)
    assert at(correlation_mm / 2) == pytest.approx(math.exp(-0.25), abs=0.04)
    assert at(2 * correlation_mm) == pytest.approx(math.exp(-4), abs=0.04)


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


@pytest.mark.slow
@settings(FUZZ, max_examples=max(200, EXAMPLES * 3))
@given(text=st.text(alphabet=st.sampled_from(NUMBER_CHARS), min_size=1, max_size=8))
def test_a_specimen_spec_reads_its_numbers_as_every_reader_does(text):
    """Issue 28.4: a spec's number is what parse_number reads (no 1_5 as 15 mm), or the spec is refused."""
    from roughsense.errors import ConfigError
    from roughsense.io.numbers import NumberError, parse_number
    from roughsense.sim.specimens import parse_specimen

    try:
        expected = float(parse_number(text))
    except NumberError:
        expected = None
    try:
        got = parse_specimen(f"rect:{text}").wavelength_mm
    except ConfigError:
        got = None
    assert got is None or got == expected, (text, got, expected)
    if expected is None:
        assert got is None


#: The gratings issue 46 keeps back for judging: never in a set the project trains or chooses on.
KEPT_BACK = ("rect:2.5:1:2", "rect:5:1:4", "rect:4:1:3", "rect:3:1:2", "rect:4:1:1", "rect:2.5:1:0.5", "rect:5:1:1",
             "rect:3:1:1", "rect:3.5:1:1", "rect:4.5:1:3.5")


def test_paper_plus_grooves_is_the_papers_14_and_8_rectangles_whose_land_is_not_half_the_period():
    from roughsense.sim.specimens import SPECIMEN_SETS

    assert SPECIMEN_SETS["paper"] == PAPER_SPECIMENS
    specs = SPECIMEN_SETS["paper+grooves"]
    assert specs[:14] == PAPER_SPECIMENS
    grooves = [parse_specimen(s) for s in specs[14:]]
    assert {(g.wavelength_mm, g.ridge_width_mm) for g in grooves} == {
        (p, round(f * p, 6)) for p in (2.0, 3.0, 4.0, 5.0) for f in (0.3, 0.7)}
    for g in grooves:
        assert g.shape == "rectangular" and g.groove_depth_mm == 1.0
        assert g.groove_width_mm == pytest.approx(g.wavelength_mm - g.ridge_width_mm) != g.ridge_width_mm
    assert [g.name for g in grooves][:2] == ["rect_2_1_0.6", "rect_2_1_1.4"]  # as parse_specimen names the specs
    kept = {parse_specimen(s).name for s in KEPT_BACK}
    assert not kept & {parse_specimen(s).name for s in specs}


def test_set_names_expand_in_place_and_an_unknown_set_is_one_line():
    from roughsense.sim.specimens import SPECIMEN_SETS, check_specimen_set, expand_specimen_sets

    assert expand_specimen_sets(["sin:3:0.5", "Paper+Grooves"]) == ("sin:3:0.5", *SPECIMEN_SETS["paper+grooves"])
    assert expand_specimen_sets(["R3"]) == ("R3",)
    with pytest.raises(ConfigError, match=r"--study builtin:SET: unknown specimen set 'groovy' \(expected one of "
                                          r"paper, paper\+grooves"):
        check_specimen_set("groovy", option="--study builtin:SET")
