"""report/figures.py: every figure stays within its pixel budget, at the dpi asked where the budget allows."""
from __future__ import annotations

import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.fuzzing import EXAMPLES, FUZZ


@pytest.mark.parametrize("size_in", [(15.0, 9.0), (8.0, 5.6), (25.2, 12.0)])
def test_the_highest_dpi_stays_within_the_pixel_budget_of_a_figure(size_in):
    """36.10: --dpi 1200, the documented maximum, took 3.5 GB and 110 s on a 108-image study."""
    import io
    import warnings

    import matplotlib.pyplot as plt
    from PIL import Image

    from roughsense.report import figures

    fig, ax = plt.subplots(figsize=size_in)
    ax.plot([0, 1], [0, 1])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        png = figures.figure_bytes(fig, "png", dpi=1200)
    width, height = Image.open(io.BytesIO(png)).size
    assert width * height <= figures.MAX_FIGURE_PIXELS
    assert width * height >= 0.5 * figures.MAX_FIGURE_PIXELS  # the tight bbox trims the margins, no more
    assert len(caught) == 1 and "--dpi 1200" in str(caught[0].message)


def test_a_figure_within_the_budget_is_drawn_at_the_dpi_asked():
    import io

    import matplotlib.pyplot as plt

    from roughsense.report import figures

    def draw():
        fig, ax = plt.subplots(figsize=(6.0, 4.0))
        ax.plot([0, 1], [1, 0])
        return fig

    from PIL import Image

    direct = io.BytesIO()
    fig = draw()
    fig.savefig(direct, format="png", dpi=300, bbox_inches="tight", metadata={"Software": None})
    plt.close(fig)
    ours, theirs = (Image.open(io.BytesIO(png)) for png in (figures.figure_bytes(draw(), "png", dpi=300), direct.getvalue()))
    assert ours.info["dpi"] == pytest.approx((300, 300), abs=0.01)  # pHYs stores dots per metre
    # matplotlib's tight box and ours (the ink plus the same pad) agree within 0.03 in: text boxes hold their
    # glyphs' ascent and descent, the ink only the glyphs
    assert all(abs(a - b) <= 0.03 * 300 for a, b in zip(ours.size, theirs.size))


def test_the_dpi_help_states_the_budget_in_force(run_cli):
    from roughsense.report.figures import MAX_FIGURE_PIXELS

    code, out, _ = run_cli("study", "--help")
    assert code == 0 and f"within {MAX_FIGURE_PIXELS / 1e6:g} Mpx" in " ".join(out.split())


@pytest.mark.slow
@settings(FUZZ, max_examples=max(40, EXAMPLES // 2))
@given(width_in=st.floats(0.5, 40.0), height_in=st.floats(0.5, 40.0), dpi=st.integers(30, 1200))
def test_every_accepted_dpi_stays_within_a_figures_pixel_budget(width_in, height_in, dpi):
    """36.10: for every figure size and every --dpi accepted, a figure is rendered within MAX_FIGURE_PIXELS, and at
    the dpi asked whenever that fits."""
    import warnings

    import matplotlib.pyplot as plt

    from roughsense.report.figures import MAX_FIGURE_PIXELS, figure_dpi

    fig = plt.figure(figsize=(width_in, height_in))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        used = figure_dpi(fig, dpi)
    plt.close(fig)
    assert width_in * height_in * used**2 <= MAX_FIGURE_PIXELS * (1 + 1e-9)
    assert used == dpi or width_in * height_in * dpi**2 > MAX_FIGURE_PIXELS


def test_specs_sort_beside_the_presets_of_their_period_and_slant_under_the_axis():
    """A spec's numbers are its period, depth and land: rect_4_1_1.2 sorts beside R4 (pre-46 its digits ran together
    into 4101.2, after R5), and specs' long names are slanted so that they stay apart."""
    from roughsense.report.figures import _specimen_order, ovl_sd_figure

    names = ["R5", "rect_4_1_1.2", "R4", "rect_2_1_0.6", "R2", "C2"]
    shapes = {n: "circular" if n.startswith("C") else "rectangular" for n in names}
    assert _specimen_order(names, shapes) == ["R2", "rect_2_1_0.6", "R4", "rect_4_1_1.2", "R5", "C2"]
    results = pd.DataFrame({"pad": "smooth", "condition": "combined", "specimen": names, "ovl": 0.5, "pred_sd": 0.1})
    perceived = pd.DataFrame({"specimen": names, "sd": 0.2})
    figure = ovl_sd_figure(results, perceived, "smooth", shapes, paper=False)
    rectangles, circles = figure.axes[0], figure.axes[1]
    assert {t.get_rotation() for t in rectangles.get_xticklabels()} == {45.0}
    assert {t.get_rotation() for t in circles.get_xticklabels()} == {0.0}  # the presets' names stay upright
