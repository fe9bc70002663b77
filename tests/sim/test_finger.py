"""The simulated finger (sim/finger.py): mechanics against Flamant's solution, the fit against the paper's
ratings (leave-one-specimen-out), and published findings on perceived roughness, one test each."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy import integrate
from scripts.finger_fitting import fit_readout, fit_spread, leave_one_out

from roughsense.errors import ConfigError
from roughsense.paper import PAPER_SPECIMENS
from roughsense.sim import finger as finger_model
from roughsense.sim.specimens import PRESETS, circular, rectangular, sinusoidal

PAPER = pd.read_csv(Path(__file__).parents[2] / "src/roughsense/data/paper/perceived_roughness.csv",
                    dtype={"specimen": str}).set_index("specimen")
RATED = [n for n in PAPER_SPECIMENS if n != "R3"]


def _magnitude(specimen, force_n=None, finger=finger_model.FINGER) -> float:
    return finger_model.magnitude(specimen, force_n=force_n, finger=finger)


def _flamant(pressure, x_mm, z_mm, a_mm):
    """sigma_x, sigma_z under a strip |s| <= a of uniform pressure: Flamant's line load integrated in real space."""
    def integral(f):
        return integrate.quad(f, -a_mm, a_mm, points=[x_mm] if abs(x_mm) < a_mm else None, limit=200)[0]

    sz = -(2 * z_mm**3 / math.pi) * integral(lambda s: 1.0 / ((x_mm - s) ** 2 + z_mm**2) ** 2)
    sx = -(2 * z_mm / math.pi) * integral(lambda s: (x_mm - s) ** 2 / ((x_mm - s) ** 2 + z_mm**2) ** 2)
    return pressure * sx, pressure * sz


@pytest.mark.parametrize("x_mm", [0.0, 0.7, 1.3, 3.0])
def test_subsurface_stress_matches_flamant_for_a_strip_load(x_mm):
    length, n, a, z, p = 400.0, 2**17, 1.0, 0.8, 10e3
    x = (np.arange(n) * (length / n) + length / 2) % length - length / 2  # centred grid
    load = np.where(np.abs(x) <= a, p, 0.0)
    sx, sz = finger_model.subsurface_stress(load, length, z)
    i = int(np.argmin(np.abs(x - x_mm)))
    ex, ez = _flamant(p, x[i], z, a)
    # the periodic images 400 mm away add about the mean pressure (p * 2a / L = 0.5 % of p): tolerance 1 % of p
    assert sx[i] == pytest.approx(ex, abs=0.01 * p)
    assert sz[i] == pytest.approx(ez, abs=0.01 * p)


def test_mean_strain_at_depth_follows_equilibrium():
    """Whatever the profile, the mean stresses at depth are sigma_x = sigma_z = -p (plane strain), so the mean
    compressive vertical strain is p (1 + nu)(1 - 2 nu) / E."""
    finger = finger_model.FINGER
    p = finger.nominal_pressure_pa(finger.force_n)
    expected = p * (1 + finger.poisson) * (1 - 2 * finger.poisson) / finger.young_pa
    for name in ("R2", "C4"):
        strain = finger_model.readout(PRESETS[name]).strain
        assert strain.mean(axis=1) == pytest.approx(np.full(finger.ridge_phases, expected), rel=1e-6)


def test_the_reference_is_one_and_geometry_not_the_name_decides():
    assert _magnitude(PRESETS["R3"]) == pytest.approx(1.0)
    assert _magnitude(rectangular(3.0, name="my-copy-of-R3")) == pytest.approx(1.0)
    assert _magnitude(circular(4.0)) == pytest.approx(_magnitude(PRESETS["C4"]))


def test_bad_finger_parameters_are_config_errors():
    with pytest.raises(ConfigError, match="young_pa"):
        finger_model.Finger(young_pa=-1.0)
    with pytest.raises(ConfigError, match="force"):
        finger_model.readout(PRESETS["R3"], force_n=0.0)


def test_committed_constants_are_the_fitting_scripts_output():
    """scripts/fit_finger_to_paper.py's numbers, recomputed: the module's constants are not hand-tuned."""
    gmean = PAPER.loc[RATED, "perceived_gmean"].to_numpy(float)
    fit = fit_readout([PRESETS[n] for n in RATED], gmean)
    assert fit.receptor_depth_mm == finger_model.FITTED_RECEPTOR_DEPTH_MM
    assert fit.saturation_strain == pytest.approx(finger_model.FITTED_SATURATION_STRAIN, rel=1e-5)
    assert fit.exponent == pytest.approx(finger_model.FITTED_EXPONENT, rel=1e-5)
    ratios = [finger_model.log_ratio(PRESETS[n]) for n in RATED]
    sd = PAPER.loc[RATED, "perceived_sd"].to_numpy(float)
    spread = fit_spread(ratios, sd / gmean, fit.exponent)
    assert spread == pytest.approx((finger_model.FITTED_SCALE_SD, finger_model.FITTED_EXPONENT_SD,
                                    finger_model.FITTED_SESSION_SD), rel=1e-5)


def test_leave_one_specimen_out_on_the_papers_13_specimens():
    """Held-out predictions: Spearman rho 0.92 and median |log error| 0.125, below the median human log-SD (0.27).

    Goal (issue 12): rho >= 0.9 and the median error below the human SD. Both met; the numbers are asserted as
    measured so that a change to the model that moves them shows up here (docs/simulator.md, "The finger")."""
    gmean = PAPER.loc[RATED, "perceived_gmean"].to_numpy(float)
    sd = PAPER.loc[RATED, "perceived_sd"].to_numpy(float)
    result = leave_one_out([PRESETS[n] for n in RATED], gmean)
    human_log_sd = float(np.median(np.sqrt(np.log1p((sd / gmean) ** 2))))
    assert human_log_sd == pytest.approx(0.268, abs=0.001)
    assert result.spearman == pytest.approx(0.919, abs=0.002)
    assert result.median_abs_log_error == pytest.approx(0.125, abs=0.002)
    assert result.spearman >= 0.9 and result.median_abs_log_error < human_log_sd
    worst = result.names[int(np.argmax(result.abs_log_errors))]
    assert worst == "R2"  # predicted 0.60 for 0.37: the model's largest miss, reported in the docs


def test_the_spread_across_people_grows_away_from_the_reference():
    """The paper's SDs (relative to the mean) are smallest near R3 and largest at the extremes; the model gets this
    from the exponent's variation between people, not from a table."""
    psych = finger_model.PSYCHOPHYSICS
    near, far = finger_model.log_ratio(PRESETS["R3.5"]), finger_model.log_ratio(PRESETS["R2"])
    assert psych.log_sd_of_medians(far) > psych.log_sd_of_medians(near) > psych.log_sd_of_medians(0.0)


# --- published qualitative findings -------------------------------------------------------------------------------

def test_roughness_rises_with_groove_width_at_fixed_land():
    """Lederman & Taylor 1972 (Percept Psychophys 12:401); Lederman 1974 (Percept Psychophys 16:385);
    Drewing 2018: at a fixed land width, perceived roughness grows with groove width (here 0.5-3 mm, lands 0.5 and
    1 mm, grooves 1 mm deep)."""
    for land in (0.5, 1.0):
        values = [_magnitude(rectangular(land + g, ridge_width_mm=land)) for g in (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)]
        assert np.all(np.diff(values) > 0), values


LANDS_MM = (0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0)


def test_land_width_over_the_cited_range_records_where_the_model_departs_from_it():
    """Lederman 1974: for narrow grooves, wider lands feel (slightly) smoother. Her plates' lands were about a
    millimetre and narrower, and there the model has the OPPOSITE sign: a known limit (docs/simulator.md, "The
    finger"), recorded here over lands 0.25-4 mm rather than hidden by testing only where it agrees.

    1 mm grooves: roughness rises with land width up to 1.25 mm (0.355 -> 0.617), is flat to 2 mm and falls only
    beyond (0.616 -> 0.523 at 4 mm). 0.5 mm grooves: irregular below 1.5 mm (a dip to 0.083 at 0.5 mm lands, where
    the 1 mm period beats with the finger's 0.5 mm ridges; without ridges the curve rises smoothly) and falling
    over 2-4 mm. The whole curve is asserted as measured, so a change of the model that moves it shows up here."""
    measured = {
        1.0: [0.355, 0.398, 0.536, 0.562, 0.617, 0.616, 0.616, 0.605, 0.571, 0.546, 0.523],
        0.5: [0.197, 0.083, 0.234, 0.195, 0.266, 0.247, 0.258, 0.251, 0.244, 0.228, 0.218],
    }
    curves = {g: np.array([_magnitude(rectangular(g + land, ridge_width_mm=land)) for land in LANDS_MM])
              for g in measured}
    for groove, values in curves.items():
        np.testing.assert_allclose(values, measured[groove], atol=0.002)
        wide = values[list(LANDS_MM).index(2.0):]
        assert np.all(np.diff(wide) < 0), (groove, values)  # Lederman's sign, but only on lands of 2-4 mm
    narrow = curves[1.0][: list(LANDS_MM).index(1.25) + 1]
    assert np.all(np.diff(narrow) > 0), curves[1.0]  # the opposite sign over the cited study's lands
    assert curves[0.5][1] == curves[0.5].min()  # the ridge beat at a 1 mm period
    ridgeless = finger_model.Finger(ridge_height_mm=0.0)  # the dip is the ridges': without them 0.5 mm lands > 0.25
    assert (_magnitude(rectangular(1.0, ridge_width_mm=0.5), finger=ridgeless)
            > _magnitude(rectangular(0.75, ridge_width_mm=0.25), finger=ridgeless))


def test_roughness_falls_again_past_a_groove_frequency_of_about_half_a_cycle_per_mm():
    """Drewing 2018: at a fixed groove width, roughness against groove frequency is an inverted U that falls once
    the frequency passes about 0.5 mm^-1. Here: 1 mm grooves, frequencies 0.15-0.8 mm^-1."""
    freqs = np.array([0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.8])
    values = np.array([_magnitude(rectangular(1 / f, ridge_width_mm=1 / f - 1.0)) for f in freqs])
    peak = freqs[int(np.argmax(values))]
    assert 0.25 <= peak <= 0.55, values
    past = values[freqs >= 0.45]
    assert np.all(np.diff(past) < 0), values
    assert values[-1] < 0.7 * values.max()


@pytest.mark.parametrize("name", ["R3", "C3", "rect:2:1:1"])
def test_roughness_rises_with_finger_force(name):
    """Lederman 1974: gratings feel rougher when pressed harder (0.25-3 N here; relative to R3 felt at 1 N)."""
    from roughsense.sim.specimens import parse_specimen

    values = [_magnitude(parse_specimen(name), force_n=f) for f in (0.25, 0.5, 1.0, 2.0, 3.0)]
    assert np.all(np.diff(values) > 0), values


@pytest.mark.parametrize("wavelength_mm", [2.0, 3.0])
def test_roughness_rises_with_amplitude_at_fixed_wavelength(wavelength_mm):
    """Deeper corrugations of the same period feel rougher (sinusoids, amplitude 0.02-1 mm). Issue 12 lists this
    finding without a source; docs/simulator.md says so."""
    values = [_magnitude(sinusoidal(wavelength_mm, a)) for a in (0.02, 0.05, 0.1, 0.2, 0.5, 1.0)]
    assert np.all(np.diff(values) > 0), values


def test_the_finger_never_reads_the_papers_tables(monkeypatch):
    """Physics ratings need no paper table at run time: with the reader broken they still come out, and the
    finger's modules do not mention the shipped results."""
    from scripts import finger_fitting

    from roughsense.sim import panel

    def refuse():
        raise AssertionError("the paper's table was read")

    monkeypatch.setattr(panel, "paper_perceived", refuse)
    table = panel.simulate_panel([PRESETS[n] for n in ("R2", "R3", "C5")], 0, ratings_from="physics")
    assert set(table["specimen"]) == {"R2", "C5"} and (table["rating"] > 0).all()
    for module in (finger_model, finger_fitting):
        text = Path(module.__file__).read_text(encoding="utf-8")
        assert "perceived_roughness" not in text and "data.paper" not in text and "paper_perceived" not in text


@given(st.lists(st.floats(0.0, 1e5), min_size=8, max_size=64), st.floats(0.05, 3.0), st.integers(0, 63))
def test_subsurface_stress_is_in_equilibrium_and_shift_equivariant(pressure, depth_mm, shift):
    """At any depth the mean vertical stress carries the mean load, and moving the load moves the field."""
    p = np.asarray(pressure)
    length = 0.1 * p.size
    sx, sz = finger_model.subsurface_stress(p, length, depth_mm)
    assert sz.mean() == pytest.approx(-p.mean(), abs=1e-9 * max(1.0, p.max()))
    k = shift % p.size
    sx2, sz2 = finger_model.subsurface_stress(np.roll(p, k), length, depth_mm)
    np.testing.assert_allclose(sz2, np.roll(sz, k), atol=1e-9 * max(1.0, p.max()))
    np.testing.assert_allclose(sx2, np.roll(sx, k), atol=1e-9 * max(1.0, p.max()))


def test_the_geometric_yardstick_is_two_parameter_least_squares_held_out():
    """finger_fitting.geometric_leave_one_out against the normal equations solved by hand, fold by fold."""
    from scripts.finger_fitting import geometric_leave_one_out

    gmean = PAPER.loc[RATED, "perceived_gmean"].to_numpy(float)
    law = geometric_leave_one_out([PRESETS[n] for n in RATED], gmean)
    period = np.array([PRESETS[n].wavelength_mm for n in RATED])
    x1, x2, y = np.log(period / 3.0), np.array([n.startswith("C") for n in RATED], float), np.log(gmean)
    for k in range(len(RATED)):
        u = np.arange(len(RATED)) != k
        a = np.array([[x1[u] @ x1[u], x1[u] @ x2[u]], [x1[u] @ x2[u], x2[u] @ x2[u]]])
        b, c = np.linalg.solve(a, [x1[u] @ y[u], x2[u] @ y[u]])
        assert law.predicted[k] == pytest.approx(math.exp(b * x1[k] + c * x2[k]), rel=1e-12)
