"""The groove model's terms (model/groove/terms.py) from contact columns, against hand arithmetic."""
from __future__ import annotations

import math

import numpy as np
import pytest

from roughsense.errors import ConfigError
from roughsense.model.groove.terms import TERM_NAMES, contact_terms, force_order, term_names

NAMES = ("land_mm@1N", "groove_mm@1N", "land_mm@2N", "groove_mm@2N", "land_mm@3N", "groove_mm@3N")


def test_terms_are_means_over_forces_of_logs_and_the_change_from_lowest_to_highest_force():
    row = np.array([[2.0, 1.0, 2.2, 0.9, 2.4, 0.8]])
    terms, names = contact_terms(row, NAMES)
    assert names == TERM_NAMES  # groove first, every term offered at three forces
    expected = [np.mean(np.log([1.0, 0.9, 0.8])), np.mean(np.log([2.0, 2.2, 2.4])), math.log(0.8 / 1.0),
                np.mean(np.log([2.0 / 3.0, 2.2 / 3.1, 2.4 / 3.2]))]
    np.testing.assert_allclose(terms[0], expected, rtol=1e-14)


def test_the_change_follows_the_forces_not_the_column_order():
    shuffled = ("land_mm@3N", "groove_mm@3N", "land_mm@1N", "groove_mm@1N")
    assert list(force_order(("3N", "1N"))) == [1, 0]
    terms, _ = contact_terms(np.array([[1.0, 0.5, 1.0, 2.0]]), shuffled)
    assert terms[0, TERM_NAMES.index("groove_change")] == pytest.approx(math.log(0.5 / 2.0))


def test_one_force_offers_no_change_term_and_extra_measures_are_ignored():
    names = ("land_mm@1N", "groove_mm@1N", "contact_fraction@1N")
    assert term_names(names) == ("log_groove_mm", "log_land_mm", "log_contact_fraction")
    terms, _ = contact_terms(np.array([[3.0, 1.0, 0.75]]), names)
    np.testing.assert_allclose(terms[0], [0.0, math.log(3.0), math.log(0.75)])


def test_an_unreadable_force_is_left_out_and_a_row_with_none_readable_is_nan():
    rows = np.array([[2.0, np.nan, 2.0, 1.0, 2.0, 4.0],  # 1N groove unreadable: the mean of the others, no change
                     [np.nan] * 6,
                     [2.0, 0.0, 2.0, -1.0, 2.0, 1.0]])  # a width of 0 or less cannot be a width: unreadable
    terms, _ = contact_terms(rows, NAMES)
    assert terms[0, 0] == pytest.approx(math.log(2.0)) and math.isnan(terms[0, 2])
    assert np.isnan(terms[1]).all()
    assert terms[2, 0] == pytest.approx(0.0) and math.isnan(terms[2, 2])


def test_contact_columns_lacking_a_width_or_of_another_shape_are_refused_in_one_line():
    with pytest.raises(ConfigError, match="reads the contact measure 'groove_mm'"):
        contact_terms(np.ones((2, 1)), ("land_mm@1N",))
    with pytest.raises(ConfigError, match="one column per contact name"):
        contact_terms(np.ones((2, 3)), NAMES[:2])
    with pytest.raises(ConfigError, match="land widths at 1N but groove widths at 2N"):
        contact_terms(np.ones((1, 2)), ("land_mm@1N", "groove_mm@2N"))


def test_a_surfaces_presses_are_read_together_as_the_geometric_mean_of_what_was_read():
    from roughsense.model.groove.terms import surface_contact

    contact = np.array([[1.0, 4.0], [4.0, np.nan], [2.0, 1.0], [np.nan, np.nan], [3.0, 0.0]])
    pooled = surface_contact(contact, ["a", "a", "b", "c", "c"])
    np.testing.assert_allclose(pooled[:2], [[2.0, 4.0], [2.0, 4.0]])  # sqrt(1 * 4); the one groove read
    np.testing.assert_array_equal(pooled[2], contact[2])  # a surface of one press keeps its own
    np.testing.assert_allclose(pooled[3:, 0], 3.0)
    assert np.isnan(pooled[3:, 1]).all()  # a zero width is no reading
    assert surface_contact(contact, None) is contact  # no surfaces: each press alone
