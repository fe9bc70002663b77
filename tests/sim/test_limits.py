"""sim/limits.py: what the twin will simulate, bounded before any work: a period of at least 4 contact-grid points,
a relief above 0 and at most 10 mm, a pad modulus from 1 kPa to 1 GPa, a panel of at most 2000 ratings a specimen."""
from __future__ import annotations

import math

import pytest

from roughsense.sim.limits import (
    MAX_PANEL_SIZE,
    MAX_PERIOD_MM,
    MIN_PERIOD_MM,
    pad_problem,
    panel_problem,
    period_problem,
    relief_problem,
)


def test_a_period_is_bounded_at_both_ends_inclusive():
    assert period_problem(MIN_PERIOD_MM, "p") is None and period_problem(MAX_PERIOD_MM, "p") is None
    for value in (MIN_PERIOD_MM * 0.999, MAX_PERIOD_MM * 1.001, math.nan, math.inf):
        problem = period_problem(value, "the wavelength")
        assert problem.startswith(f"the wavelength must be from {MIN_PERIOD_MM:g} to {MAX_PERIOD_MM:g} mm")


def test_a_relief_is_above_zero_and_at_most_ten_mm():
    assert relief_problem(1e-9, "depth") is None and relief_problem(10.0, "depth") is None
    assert relief_problem(0.0, "depth") == "depth must be above 0 and at most 10 mm, got 0"
    assert relief_problem(10.5, "depth") == "depth must be above 0 and at most 10 mm, got 10.5"


@pytest.mark.parametrize("participants, sessions", [(MAX_PANEL_SIZE, 1), (40, 50), (1, 1)])
def test_a_panel_up_to_the_limit_is_simulated(participants, sessions):
    assert panel_problem(participants, sessions) is None


def test_a_larger_panel_is_refused_with_its_product():
    assert panel_problem(1000, 3) == ("participants x sessions = 1000 x 3 = 3000, above the simulated panel's limit "
                                      f"of {MAX_PANEL_SIZE}")


def test_a_pad_names_its_first_value_out_of_bounds():
    assert pad_problem(period_mm=0.45, ridge_height_mm=0.05, modulus_pa=1e5) is None
    assert pad_problem(modulus_pa=1e10) == "pad modulus must be from 0.001 to 1000 MPa, got 10000"
    assert pad_problem(period_mm=0.0, modulus_pa=1e10).startswith("fingerprint period must be from")
