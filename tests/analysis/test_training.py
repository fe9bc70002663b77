"""``analysis/training.py``: what ``roughsense fit`` trains when --model is not given, by the study's own design."""
from __future__ import annotations

import pytest

from roughsense.analysis.training import train_model
from roughsense.io.study import read_study
from roughsense.sim.config import SimulationConfig, with_image_size
from roughsense.sim.simulate import simulate_study

HALF_LAND = ("R2", "R3", "R4", "R5", "C3")
GROOVES = (*HALF_LAND, "rect:4:1:1.2", "rect:3:1:2.1")


@pytest.fixture(scope="module")
def twin(tmp_path_factory):
    """A small smooth-pad study of the twin at 2 N: the paper's half-land rectangles, and two more whose land is not
    half the period."""
    config = SimulationConfig(pads=("smooth",), specimens=GROOVES, forces_n=(2.0,), repetitions=2, seed=3,
                              participants=3, sessions=2)
    return read_study(simulate_study(tmp_path_factory.mktemp("twin") / "study", with_image_size(config, 1920, 170),
                                     jobs=1))


def test_fits_default_is_the_groove_model_where_the_rectangles_vary_land_against_groove(twin):
    """The design tells period from groove width only where the rectangles vary land at a period: there the groove
    model's terms can earn their place, and fit trains it; the paper's design (one geometry) keeps the peak law."""
    assert train_model(twin, pad="smooth", condition="2N").family == "groove"
    half = twin.specimens[twin.specimens["specimen"].isin(HALF_LAND)]
    paper_like = type(twin)(**{**twin.__dict__, "specimens": half,
                               "manifest": twin.manifest[twin.manifest["specimen"].isin(HALF_LAND)]})
    assert train_model(paper_like, pad="smooth", condition="2N").family == "peak-law"
    assert train_model(twin, pad="smooth", condition="2N", model="peak-law").family == "peak-law"  # as asked
