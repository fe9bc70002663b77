"""The simulated panel reproduces the paper's perceived roughness in expectation, with the paper's spread."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from roughsense.errors import ConfigError
from roughsense.paper import PAPER_SPECIMENS
from roughsense.sim import panel
from roughsense.sim.specimens import PRESETS, parse_specimen

PAPER = pd.read_csv(__import__("pathlib").Path(__file__).parents[2] / "src/roughsense/data/paper/perceived_roughness.csv",
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


def test_default_panel_is_unchanged_for_the_papers_presets():
    """The default study's ratings (seed 0 and 1, the simulator's spawn key) are byte-identical to those before
    the finger model existed (issue 12: ``--ratings-from paper`` keeps today's behaviour for the presets)."""
    import hashlib

    specimens = [PRESETS[s] for s in PAPER_SPECIMENS]
    expected = {0: "f6c807e4a24bdc581fb8a68b6fb72872b1a4e09fce55639ca6a0313a549d88bb",
                1: "58ff67d2593e43ab9f776e5f28daae0427d4192d9265a9b204e98dab1257933a"}
    for seed, digest in expected.items():
        for kwargs in ({}, {"ratings_from": "paper"}):
            table = panel.simulate_panel(specimens, seed, spawn_key=(4,), **kwargs)
            assert hashlib.sha256(table.to_csv(index=False).encode()).hexdigest() == digest


def test_ratings_source_per_specimen():
    from roughsense.sim import finger

    assert panel.percept(PRESETS["R4"]).source == "paper"
    assert panel.percept(PRESETS["R4"]).gmean == PAPER.loc["R4", "perceived_gmean"]
    for spec in (parse_specimen("rect:3.2"), parse_specimen("sin:3:0.5"), parse_specimen("rand:1.5:0.2")):
        p = panel.percept(spec)
        assert p.source == "physics" and p.gmean == pytest.approx(finger.magnitude(spec))
    physics = panel.percept(PRESETS["R4"], ratings_from="physics")
    assert physics.source == "physics" and physics.gmean == pytest.approx(finger.magnitude(PRESETS["R4"]))
    # depth matters now (the old power law of groove width rated a shallow sinusoid like a deep one)
    assert panel.percept(parse_specimen("sin:3:0.05")).gmean < panel.percept(parse_specimen("sin:3:0.5")).gmean
    with pytest.raises(ConfigError, match="ratings-from"):
        panel.percept(PRESETS["R4"], ratings_from="table")
    with pytest.raises(ConfigError, match="ratings-from"):
        panel.simulate_panel([PRESETS["R4"]], 0, ratings_from="")


def test_physics_panels_aggregate_to_the_models_percept():
    """Over 300 seeded panels: the paper's aggregation (median over sessions, geometric mean over people) centres
    on the model's typical rating, the SD across people's medians on its spread, and each person's scale is shared
    by the specimens they rate (their medians for two specimens correlate across people)."""
    specs = [parse_specimen("rect:4:1:1.5"), parse_specimen("sin:3:0.3")]
    aggregated, sds, pairs = {s.name: [] for s in specs}, {s.name: [] for s in specs}, []
    for seed in range(300):
        table = panel.simulate_panel(specs, seed)
        medians = table.groupby(["specimen", "participant"])["rating"].median().unstack("participant")
        for s in specs:
            aggregated[s.name].append(np.exp(np.log(medians.loc[s.name]).mean()))
            sds[s.name].append(medians.loc[s.name].std(ddof=1))
        pairs.append(np.corrcoef(np.log(medians.loc[specs[0].name]), np.log(medians.loc[specs[1].name]))[0, 1])
    for s in specs:
        p = panel.percept(s)
        assert np.exp(np.mean(np.log(aggregated[s.name]))) == pytest.approx(p.gmean, rel=0.03)
        assert np.mean(sds[s.name]) == pytest.approx(p.sd, rel=0.15)
    assert np.mean(pairs) > 0.3


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


def test_physics_ratings_do_not_depend_on_the_other_specimens():
    def one(names, seed=7):
        table = panel.simulate_panel([parse_specimen(n) for n in names], seed, ratings_from="physics")
        rows = table[table["specimen"] == "sin_3_0.5"].sort_values(["participant", "session"])
        return rows[["participant", "session", "rating"]].reset_index(drop=True)

    alone = one(["sin:3:0.5"])
    assert len(alone) == 10 * 3  # the name filter matched (spec names use '_'): the comparison is not vacuous
    pd.testing.assert_frame_equal(one(["sin:3:0.5", "R2", "C5"]), alone)
