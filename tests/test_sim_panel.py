"""The simulated panel reproduces the paper's perceived roughness in expectation, with the paper's spread."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from roughsense.sim import panel
from roughsense.sim.specimens import PAPER_SPECIMENS, PRESETS, parse_specimen

PAPER = pd.read_csv(__import__("pathlib").Path(__file__).parents[1] / "src/roughsense/data/paper/perceived_roughness.csv",
                    dtype={"specimen": str}).set_index("specimen")


@pytest.mark.parametrize("name", [s for s in PAPER_SPECIMENS if s != "R3"])
def test_many_panels_reproduce_paper_mean_and_sd(name):
    gmean, sd = PAPER.loc[name, ["perceived_gmean", "perceived_sd"]]
    ratings = panel.draw_log_ratings(gmean, sd, np.random.default_rng(11), panels=3000)
    medians = np.median(ratings, axis=2)  # over sessions
    aggregated = np.exp(np.log(medians).mean(axis=1))  # geometric mean over participants
    assert aggregated.mean() == pytest.approx(gmean, rel=0.01)
    assert medians.std(axis=1, ddof=1).mean() == pytest.approx(sd, rel=0.04)


def test_panel_table_has_the_paper_design():
    specimens = [PRESETS[s] for s in PAPER_SPECIMENS]
    table = panel.simulate_panel(specimens, 0)
    assert len(table) == 10 * 3 * 13 == 390
    assert "R3" not in set(table["specimen"])
    counts = table.groupby(["participant", "session"]).size()
    assert (counts == 13).all() and len(counts) == 30
    assert (table["rating"] > 0).all()


def test_model_based_specimens_follow_the_fitted_power_law():
    a, b = panel.power_law()["sharp"]
    spec = parse_specimen("rect:3.2")
    p = panel.percept(spec)
    assert p.source == "model" and p.gmean == pytest.approx(a * 1.6**b)
    assert panel.percept(PRESETS["R4"]).source == "paper"
    # the fit follows the paper's values: within 20 % of every inner rectangular grating's perceived roughness
    for lam in (2.5, 3.0, 3.5, 4.0, 4.5):
        assert a * (lam / 2) ** b == pytest.approx(PAPER.loc[f"R{lam:g}", "perceived_gmean"], rel=0.2)
    a_r, b_r = panel.power_law()["rounded"]
    assert panel.percept(parse_specimen("sin:3:0.5")).gmean == pytest.approx(a_r * 1.5**b_r)
    assert b > 0 and b_r > 0  # wider grooves feel rougher


def test_a_specimens_ratings_do_not_depend_on_the_other_specimens():
    def c5(names, seed=7):
        table = panel.simulate_panel([PRESETS[n] for n in names], seed)
        rows = table[table["specimen"] == "C5"].sort_values(["participant", "session"])
        return rows[["participant", "session", "rating"]].reset_index(drop=True)

    with_r2 = c5(PAPER_SPECIMENS)
    assert len(with_r2) == 30
    pd.testing.assert_frame_equal(with_r2, c5([n for n in PAPER_SPECIMENS if n != "R2"]))
    pd.testing.assert_frame_equal(with_r2, c5(["C5"]))
    assert not np.array_equal(with_r2["rating"], c5(PAPER_SPECIMENS, seed=8)["rating"])  # the seed still matters
