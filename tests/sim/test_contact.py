"""Contact mechanics of the twin against analytic solutions and against ContactMechanics."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from roughsense.errors import ConfigError
from roughsense.sim import contact
from roughsense.sim.pads import make_pad
from roughsense.sim.specimens import PRESETS

E_STAR = 0.17e6 / (1 - 0.49**2)
N = 4096


def _grid(length_mm: float, n: int = N) -> np.ndarray:
    return np.arange(n) * (length_mm / n)


def _hertz_fraction(p: float, lam: float) -> float:
    radius = lam / 2.0
    return 2.0 * math.sqrt(4.0 * p * lam * radius / (math.pi * E_STAR)) / lam


def test_contact_modulus_of_pvc_plastisol():
    assert make_pad("smooth").contact_modulus_pa == pytest.approx(0.17e6 / (1 - 0.49**2))
    assert make_pad("smooth").contact_modulus_pa == pytest.approx(0.225e6, rel=0.01)  # E/(1 - nu^2): E = 0.17 MPa, nu = 0.49


def test_nominal_pressure_is_force_over_specimen_footprint():
    assert contact.nominal_pressure_pa(1.0) == pytest.approx(2000.0)
    assert contact.nominal_pressure_pa(3.0) == pytest.approx(6000.0)


@pytest.mark.parametrize("ratio", [0.05, 0.2, 0.5, 0.8, 0.95])
def test_westergaard_sinusoid(ratio):
    lam, amp = 3.0, 0.01
    x = _grid(lam)
    p_star = math.pi * E_STAR * amp / lam
    sol = contact.solve_periodic(amp * np.cos(2 * math.pi * x / lam), lam, ratio * p_star, E_STAR)
    a = math.asin(math.sqrt(ratio)) * lam / math.pi  # p = p* sin^2(pi a / lambda)
    assert sol.contact_fraction == pytest.approx(2 * a / lam, rel=0.02)
    assert sol.pressure_pa.mean() == pytest.approx(ratio * p_star, rel=1e-9)


@pytest.mark.parametrize("lam", [2.0, 5.0])
def test_periodic_hertz_in_the_small_contact_limit(lam):
    p = 200.0  # a / lambda ~ 0.025: neighbours do not interact
    sol = contact.solve_periodic(PRESETS[f"C{lam:g}"].height_mm(_grid(lam)), lam, p, E_STAR)
    assert sol.contact_fraction == pytest.approx(_hertz_fraction(p, lam), rel=0.02)


@pytest.mark.parametrize("force_n", [1.0, 2.0, 3.0])
def test_touching_semicylinders_match_contactmechanics(force_n):
    from ContactMechanics import PeriodicFFTElasticHalfSpace
    from ContactMechanics.Optimization import constrained_conjugate_gradients
    from SurfaceTopography import UniformLineScan

    lam = 2.0
    x = _grid(lam)
    h = PRESETS["C2"].height_mm(x)
    p = contact.nominal_pressure_pa(force_n)
    ours = contact.solve_periodic(h, lam, p, E_STAR)
    substrate = PeriodicFFTElasticHalfSpace((N,), E_STAR, physical_sizes=(lam,))
    ref = constrained_conjugate_gradients(substrate, UniformLineScan(h, lam, periodic=True),
                                          external_force=p * lam, pentol=1e-10)
    ref_fraction = float(np.mean(ref.jac > 0))
    assert abs(ours.contact_fraction - ref_fraction) <= 2.0 / N
    ref_pressure = ref.jac / (lam / N)
    assert np.abs(ours.pressure_pa - ref_pressure).max() <= 0.01 * ref_pressure.max()
    # ContactMechanics at 4096 points per period: the solved fraction falls below Hertz by 1.0 %, 1.6 %, 2.5 % at 1, 2, 3 N
    shortfall = {1.0: 0.010, 2.0: 0.016, 3.0: 0.025}[force_n]
    assert 1 - ours.contact_fraction / _hertz_fraction(p, lam) == pytest.approx(shortfall, abs=0.003)


@given(st.sampled_from([2.0, 2.5, 3.0, 4.5, 5.0]))
def test_semicylinder_contact_fraction_does_not_depend_on_wavelength(lam):
    n = 1024
    sol = contact.solve_periodic(PRESETS[f"C{lam:g}"].height_mm(_grid(lam, n)), lam, 4000.0, E_STAR)
    ref = contact.solve_periodic(PRESETS["C2"].height_mm(_grid(2.0, n)), 2.0, 4000.0, E_STAR)
    assert sol.contact_fraction == pytest.approx(ref.contact_fraction, abs=1.5 / n)


@pytest.mark.parametrize(("lam", "p"), [(2.0, 2000.0), (4.0, 6000.0)])
def test_rectangular_grating_bulge_into_groove(lam, p):
    sol = contact.solve_periodic(PRESETS[f"R{lam:g}"].height_mm(_grid(lam)), lam, p, E_STAR)
    b = lam / 4.0  # half the land width
    bulge = (2 * p * lam / (math.pi * E_STAR)) * math.log(1 / math.tan(math.pi * b / (2 * lam)))
    depth_left = sol.gap_mm[0]  # groove centre (the land is centred at lambda / 2)
    assert 1.0 - depth_left == pytest.approx(bulge, rel=0.02)
    assert sol.contact_fraction == pytest.approx(0.5, abs=2.0 / N)  # only the lands touch


@given(st.integers(0, 2**32 - 1), st.floats(500.0, 20000.0))
def test_solution_is_complementary_and_balanced(seed, p):
    rng = np.random.default_rng(seed)
    n, length = 512, 4.0
    k = np.fft.rfftfreq(n, d=length / n)
    spec = np.exp(-((k * 0.8) ** 2)) * (rng.standard_normal(k.size) + 1j * rng.standard_normal(k.size))
    spec[0] = 0
    h = np.fft.irfft(spec, n)
    h *= 0.02 / h.std()
    sol = contact.solve_periodic(h, length, p, E_STAR)
    assert sol.pressure_pa.mean() == pytest.approx(p, rel=1e-9)
    assert (sol.pressure_pa >= 0).all() and (sol.gap_mm >= 0).all()
    assert (sol.gap_mm[sol.contact] == 0).all()
    # ...and the same before the clean-up: the solver's own gap does not penetrate outside the contact, closes
    # inside it, and its converged step carries the load without the final rescaling
    tol = 1e-6 * np.ptp(h)
    assert sol.raw_gap_mm[~sol.contact].min(initial=0.0) >= -tol
    assert np.abs(sol.raw_gap_mm[sol.contact]).max() <= tol
    assert sol.balance == pytest.approx(1.0, abs=1e-6)
    assert sol.change < 1e-9
    # the elastic surface sits on the profile where it touches: u - h is constant over the contact
    u = np.fft.irfft(np.fft.rfft(sol.pressure_pa) * np.r_[0, 2 / (E_STAR * 2 * np.pi * k[1:])], n)
    lift = (u - h)[sol.contact]
    assert np.ptp(lift) <= 1e-3 * np.ptp(h)


def test_periodic_domain_holds_whole_periods():
    assert contact.periodic_domain(2.5, 1.0) == (5.0, 1.0)
    assert contact.periodic_domain(3.0, None) == (3.0, None)
    length, pad = contact.periodic_domain(2.5, 0.7)
    assert length == pytest.approx(17.5) and pad == pytest.approx(0.7)
    length, pad = contact.periodic_domain(3.0, 1 / math.pi)  # incommensurate: stretched to fit, by < 1 %
    assert length / pad == pytest.approx(round(length / pad)) and pad == pytest.approx(1 / math.pi, rel=0.01)


def test_solver_that_runs_out_of_iterations_says_so():
    x = _grid(3.0, 512)
    with pytest.raises(contact.ContactNotConverged, match="did not converge in 3 iterations"):
        contact.solve_periodic(0.01 * np.cos(2 * math.pi * x / 3.0), 3.0, 500.0, E_STAR, max_iter=3)
    assert issubclass(contact.ContactNotConverged, ConfigError)  # one line at the CLI, exit 2


def _grating_under_fingerprint(name: str) -> tuple[np.ndarray, float]:
    """A preset grating plus the fingerprint pad's ridges on the trial's periodic domain: heights and length."""
    pad = make_pad("fingerprint")
    length, pad_period = contact.periodic_domain(PRESETS[name].period_mm, pad.period_mm)
    x = _grid(length, contact.grid_points(length))
    return PRESETS[name].height_mm(x) + pad.height_mm(x - 0.3, period_mm=pad_period), length


@pytest.mark.parametrize("name", ["C3", "R4"])
def test_warm_start_reaches_the_same_contact_in_fewer_steps(name):
    h, length = _grating_under_fingerprint(name)
    low = contact.solve_periodic(h, length, 2600.0, E_STAR, tol=1e-8)
    cold = contact.solve_periodic(h, length, 3400.0, E_STAR, tol=1e-8)
    warm = contact.solve_periodic(h, length, 3400.0, E_STAR, tol=1e-8, initial_pressure_pa=low.pressure_pa)
    assert warm.iterations < cold.iterations
    assert np.array_equal(warm.contact, cold.contact)
    assert np.abs(warm.gap_mm - cold.gap_mm).max() < 1e-6 * np.ptp(h)  # within the solver's tolerance
    assert warm.pressure_pa.mean() == pytest.approx(3400.0)


@pytest.mark.parametrize("name", ["C3", "R4"])
def test_levels_solved_together_are_the_single_level_solutions(name):
    """A batch shares calls, not arithmetic: each level is the contact its own solve finds (to the tolerance)."""
    h, length = _grating_under_fingerprint(name)
    pressures = [900.0, 2600.0, 4100.0, 9000.0]
    together = contact.solve_periodic_many(h, length, pressures, E_STAR, tol=1e-8)
    reversed_order = contact.solve_periodic_many(h, length, pressures[::-1], E_STAR, tol=1e-8)[::-1]
    for pressure, batch, backwards in zip(pressures, together, reversed_order):
        alone = contact.solve_periodic(h, length, pressure, E_STAR, tol=1e-8)
        assert batch.pressure_pa.mean() == pytest.approx(pressure)
        assert np.array_equal(batch.contact, alone.contact)
        assert np.abs(batch.gap_mm - alone.gap_mm).max() < 1e-6 * np.ptp(h)
        assert np.abs(backwards.gap_mm - batch.gap_mm).max() < 1e-6 * np.ptp(h)
        assert batch.iterations == alone.iterations  # the same iteration, step for step
    assert len({s.iterations for s in together}) > 1  # each level left the batch when it had converged


@pytest.mark.parametrize("pressures", [[], [1000.0, -5.0], [float("nan")]])
def test_a_batch_needs_positive_pressures(pressures):
    x = _grid(3.0, 256)
    with pytest.raises(ConfigError, match="positive"):
        contact.solve_periodic_many(0.01 * np.cos(2 * math.pi * x / 3.0), 3.0, pressures, E_STAR)


@pytest.mark.parametrize("modulus_pa", [1e-300, 1e308])
def test_an_absurd_pad_modulus_raises_no_numpy_warning(modulus_pa):
    """A grating pressed by a pad of absurd stiffness: one error of ours (or a solution), never numpy's warnings."""
    from roughsense.sim.contact import ContactNotConverged, solve_periodic_many

    x = np.linspace(0.0, 4.0, 400, endpoint=False)
    height = np.where(x % 2.0 < 1.0, 0.5, 0.0)  # rect:2 mm, 0.5 mm deep
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any numpy RuntimeWarning fails the test
        try:
            solve_periodic_many(height, 4.0, [2622.0], modulus_pa)
        except ContactNotConverged as exc:
            assert f"overflowed at iteration 1: a contact modulus of {modulus_pa:g} Pa" in str(exc)
        else:
            assert modulus_pa > 1  # an infinitely stiff pad is a solution: only the soft one overflows
