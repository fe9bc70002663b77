"""The report folder: files, schemas, the paper's values beside ours, and a real browser rendering it."""
from __future__ import annotations

import os
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from roughsense import paper
from roughsense.analysis.presses import presses_needed_by_curve
from roughsense.analysis.results import Provenance
from roughsense.analysis.study_analysis import analyse_study
from roughsense.analysis.unseen import headline_condition
from roughsense.errors import OutputExistsError
from roughsense.model.registry import names as family_names
from roughsense.report import write_report
from roughsense.report.control_tables import control_text, permutation_p_text
from roughsense.report.provenance import figure_stamp
from tests.analysis.test_study_analysis import synthetic_study


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory):
    study, features = synthetic_study(repetitions=4, seed=3)
    analysis = analyse_study(study, features=features, max_components=6, n_permutations=9)
    out = tmp_path_factory.mktemp("report") / "report"
    write_report(analysis, out, meta={"source": "synthetic test study"})
    return out


@pytest.fixture(scope="module")
def simulated_analysis():
    """The same kind of study, but study.toml has a [simulation] table: every label must say so (analysed once for
    the module; read-only)."""
    study, features = synthetic_study(repetitions=2, seed=6)
    study.extra = {"simulation": {"seed": 42, "simulator": "roughsense.sim", "repetitions": 2}}
    return analyse_study(study, features=features, max_components=2, n_permutations=0)


#: The simulated report's meta data; its date fixed, so another rendering of it can be compared byte for byte.
SIMULATED_META = {"source": "synthetic test study", "generated": "fixed"}


@pytest.fixture(scope="module")
def simulated_report_dir(tmp_path_factory, simulated_analysis):
    out = tmp_path_factory.mktemp("simulated") / "report"
    write_report(simulated_analysis, out, meta=SIMULATED_META)
    return out


@pytest.fixture(scope="module")
def smooth_simulated_analysis():
    """One pad of the simulated kind (analysed once for the module; read-only)."""
    study, features = synthetic_study(repetitions=2, seed=6, pads=("smooth",))
    study.extra = {"simulation": {"seed": 42}}
    return analyse_study(study, features=features, max_components=2, n_permutations=0)


def _stamp_pixels(png: Path) -> int:
    """Pixels in the colour of the 'SIMULATED DATA' stamp (#b00020)."""
    import numpy as np
    from PIL import Image

    rgb = np.asarray(Image.open(png).convert("RGB")).astype(int)
    return int((np.abs(rgb - np.array([176, 0, 32])).sum(axis=2) < 40).sum())


def test_simulated_and_real_studies_are_labelled(report_dir, simulated_report_dir):
    real = (report_dir / "index.html").read_text()
    simulated = (simulated_report_dir / "index.html").read_text()
    assert 'id="simulated"' in simulated and re.search(r"simulation seed\s+42", simulated)
    assert "drawn from the paper&#39;s Table 1" in simulated and "tuned" in simulated
    assert 'id="simulated"' not in real and "SIMULATED" not in real and "user data" in real
    for png in simulated_report_dir.glob("*.png"):  # every figure of a simulated study carries the stamp
        assert _stamp_pixels(png) > 50, png.name
    for png in report_dir.glob("*.png"):
        assert _stamp_pixels(png) == 0, png.name
    claims = pd.read_csv(simulated_report_dir / "claims.csv").set_index(["key", "cv"])
    assert claims.loc[("ratings_rise", "none"), "basis"].startswith("property of the simulator")


def test_paper_values_only_where_the_design_matches(tmp_path, quick_figures):
    study, features = synthetic_study(repetitions=2, seed=8, pads=("smooth",))
    keep = ["R2", "R3", "R4", "C3", "C5"]
    study.specimens = study.specimens[study.specimens.specimen.isin(keep)].reset_index(drop=True)
    study.ratings = study.ratings[study.ratings.specimen.isin(keep)]
    features = features[features.specimen.isin(keep)]
    analysis = analyse_study(study, features=features, max_components=2, n_permutations=0)
    assert analysis.paper_pads == () and "not the paper's 14" in analysis.paper_note
    write_report(analysis, tmp_path / "custom")
    html = (tmp_path / "custom" / "index.html").read_text()
    assert html.count('id="paper-note"') == 1 and "not the paper&#39;s 14" in html
    body = html.split("</header>")[1].replace('<span class="paper">beneath it</span>', "")
    # The paper's own predictions keep their section (they are judged there, not compared with ours).
    body = body.split('<h2 id="predictive">')[0] + body.split('<h2 id="components">')[1]
    assert 'class="paper"' not in body


def test_no_paper_values_on_the_loso_figure(simulated_analysis):
    from roughsense.report import figures

    analysis = simulated_analysis  # its [simulation] table changes labels, not the results drawn here
    for cv, expected in (("loo", True), ("loso", False)):
        fig = figures.predicted_vs_perceived_figure(analysis.results(cv), analysis.perceived, cv)
        labels = {line.get_label() for ax in fig.axes for line in ax.get_lines()}
        assert ("paper, combined" in labels) == expected
        figures.plt.close(fig)


def test_tables_say_their_predictions_are_out_of_fold(report_dir):
    html = (report_dir / "index.html").read_text()
    for title in ("Perceived and predicted roughness, smooth pad, LOO (mean ± SD)",
                  "Root mean squared error (RMSE), fingerprint pad, LOSO"):
        caption = html.split(title, 1)[1].split("</p>", 1)[0]
        assert "out of fold" in caption and "does not say" in caption


def test_report_files_and_schemas(report_dir):
    names = {p.name for p in report_dir.iterdir()}
    assert {"index.html", "results.csv", "results_loso.csv", "cv.csv", "tests.csv", "predictions.csv"} <= names
    assert {"cv_curves.png", "spectra_smooth.png", "ovl_sd_fingerprint.png", "predicted_vs_perceived_loo.png",
            "predicted_vs_perceived_loso_peak-law.png", "unseen_surfaces.png"} <= names
    paper_columns = list(paper.paper_results().columns)
    for name in ("results.csv", "results_loso.csv"):  # the paper's columns, then ours (added, never renamed)
        results = pd.read_csv(report_dir / name)
        assert list(results.columns) == paper_columns + ["predictive_sd", "ovl_predictive", "model"]
        assert (results["model"].value_counts() == 2 * 14 * 4).all() and set(results["model"]) == set(family_names())
    controls = pd.read_csv(report_dir / "controls.csv")
    assert list(controls.columns[:7]) == ["pad", "condition", "cv", "rmse", "null_rmse", "permutation_p",
                                          "n_permutations"]
    assert list(controls.columns[-2:]) == ["seed", "model"]
    assert len(controls) == 2 * 4 * 2 * len(family_names()) and (controls["n_permutations"] == 9).all()
    assert (controls.groupby("model").size() == 2 * 4 * 2).all()
    assert list(pd.read_csv(report_dir / "predictions.csv").columns)[-1] == "model"
    claims = pd.read_csv(report_dir / "claims.csv")
    assert list(claims.columns[:6]) == ["claim", "pad", "cv", "statistic", "p", "verdict"]
    assert set(claims["verdict"]) <= {"reproduced", "not reproduced", "undetermined", "not evidence", "premise failed",
                                      "not testable"}
    assert {"loo", "loso"} <= set(claims["cv"])
    cv = pd.read_csv(report_dir / "cv.csv")
    assert list(cv.columns) == ["pad", "condition", "cv", "n_components", "rmse", "model"]
    assert set(cv["cv"]) == {"loo", "loso"}
    assert list(pd.read_csv(report_dir / "tests.csv").columns[:4]) == ["comparison", "statistic", "p", "p_adjusted"]
    for png in report_dir.glob("*.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


class _Tables(HTMLParser):
    """The report's tables by title: rows of (ours, paper) cells, read back from the HTML."""

    def __init__(self):
        super().__init__()
        self.tables, self._title, self._row, self._cell, self._in = {}, "", None, None, None

    def handle_starttag(self, tag, attrs):
        if tag == "h3":
            self._in, self._title = "title", ""
        elif tag == "table":
            self.tables[self._title] = []
        elif tag == "tr":
            self._row = []
        elif tag in ("td", "th"):
            self._cell, self._in = ["", ""], "ours"
        elif tag == "span" and ("class", "paper") in attrs and self._in == "ours":
            self._in = "paper"

    def handle_endtag(self, tag):
        if tag == "h3":
            self._in = None
        elif tag in ("td", "th"):
            self._row.append(tuple(c.strip() for c in self._cell))
            self._in = None
        elif tag == "tr":
            self.tables[self._title].append(self._row)
        elif tag == "span" and self._in == "paper":
            self._in = "ours"

    def handle_data(self, data):
        if self._in == "title":
            self._title += data
        elif self._in == "ours":
            self._cell[0] += data
        elif self._in == "paper":
            self._cell[1] += data


def _rows(html: str, title: str) -> list[dict]:
    parser = _Tables()
    parser.feed(html)
    rows = parser.tables[title]
    header = [c[0].removesuffix(" †") for c in rows[0]]  # † flags a model that fails its controls
    return [dict(zip(header, row)) for row in rows[1:]]


def _table(html: str, title: str) -> dict:
    """Rows keyed by their first cell (the specimen, or the pad)."""
    return {row.pop(next(iter(row)))[0]: row for row in _rows(html, title)}


def test_report_shows_the_papers_values_in_the_right_cells(report_dir):
    html = (report_dir / "index.html").read_text()
    rmse = _table(html, "Root mean squared error (RMSE), fingerprint pad, LOO")
    assert rmse["R2"]["Dataset 1 N"][1] == "0.49" and rmse["C5"]["Dataset combination"][1] == "0.31"
    assert _table(html, "Root mean squared error (RMSE), smooth pad, LOO")["R2"]["Dataset 1 N"][1] == "0.26"
    # Summary rows: the values the paper prints (Table 5's rectangular row does not follow from its own cells).
    ovl = _table(html, "Overlap coefficient (OVL), smooth pad, LOO")
    assert ovl["Rectangular: mean ± SD"]["Dataset 1 N"][1] == "0.65 ± 0.16"
    assert ovl["R3"]["Dataset 1 N"] == ("—", "")  # no OVL for the reference, ours or the paper's
    assert rmse["Overall: mean ± SD"]["Dataset combination"][1] == "0.21 ± 0.07"
    assert rmse["Rectangular: mean ± SD"]["Dataset 1 N"][1] == ""  # Table 3 prints no rectangular row
    perceived = _table(html, "Perceived and predicted roughness, fingerprint pad, LOO (mean ± SD)")
    assert perceived["C5"]["Perceived"][1] == "1.72 ± 0.64"
    assert perceived["R2"]["Dataset 2 N"][1] == "0.75 ± 0.23"
    # Under LOSO the paper has no predictions: only its perceived values appear.
    loso = _table(html, "Perceived and predicted roughness, fingerprint pad, LOSO (mean ± SD)")
    assert loso["C5"]["Perceived"][1] == "1.72 ± 0.64"
    assert all(cells[c][1] == "" for cells in loso.values() for c in cells if c.startswith("Dataset"))
    components = _table(html, "Number of PLS components chosen by cross-validation")
    assert components["fingerprint"]["LOO: components"][1] == "12"  # rows keyed by pad: the last one, combined
    assert components["fingerprint"]["LOO: RMSE"][1] == "0.22326"
    tests = {row["Comparison"][0]: row for row in _rows(html, "Wilcoxon signed-rank tests on per-specimen RMSE")
             if row["CV"][0] == "LOO"}
    assert tests["fingerprint: combined vs 1N"]["p (adjusted)"][1] == "0.0048"
    assert tests["fingerprint: combined vs 3N"]["p"][1] == "0.00012"  # the paper's 1.2e-4 is unadjusted
    assert html.count("<table>") >= 2 + 2 * 2 * 3 + 1  # summary, components, 2 CV x 2 pads x 3, tests
    assert "src=\"http" not in html and "href=\"http" not in html  # self-contained, offline


def test_report_refuses_a_non_empty_folder_without_force(report_dir, tmp_path, quick_figures):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    study, features = synthetic_study(repetitions=2, seed=4)
    analysis = analyse_study(study, features=features, max_components=2, cv_schemes=("loo",), n_permutations=0)
    with pytest.raises(OutputExistsError):
        write_report(analysis, mine)
    write_report(analysis, mine, force=True)
    assert (mine / "notes.txt").read_text() == "keep me"
    assert (mine / "index.html").is_file() and not (mine / "results_loso.csv").exists()


def _chromium() -> tuple[str, str] | None:
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    return (browser, driver) if browser and driver else None


def _headless_chromium(window: str):
    """A headless Chromium of the given window size ("W,H"); skipped where it is missing, a failure in CI."""
    found = _chromium()
    if found is None:
        if os.environ.get("CI"):
            pytest.fail("CI must install Debian's chromium and chromium-driver (see .ci/run)")
        pytest.skip("chromium/chromedriver not installed")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    browser, driver_path = found
    options = webdriver.ChromeOptions()
    options.binary_location = browser
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 f"--window-size={window}"):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(executable_path=driver_path), options=options)


@pytest.mark.browser
def test_report_renders_in_headless_chromium(report_dir, simulated_report_dir):
    from selenium.webdriver.common.by import By

    driver = _headless_chromium("1280,2000")
    try:
        driver.get((report_dir / "index.html").resolve().as_uri())
        assert "roughsense report" in driver.title
        tables = driver.find_elements(By.TAG_NAME, "table")
        assert len(tables) >= 15
        answer = driver.find_element(By.CSS_SELECTOR, "#answer table.answer-table")
        assert tables[0] == answer and answer.is_displayed()  # the first screen's table comes first
        unseen = driver.find_element(By.XPATH, "//h2[@id='unseen']/following::table[1]")
        first_rows = unseen.find_elements(By.CSS_SELECTOR, "tbody tr")
        assert len(first_rows) == len(family_names()) * 2 * 4  # a grating left out: models x pads x conditions
        images = driver.find_elements(By.CSS_SELECTOR, "figure img")
        assert len(images) >= 6
        widths = [driver.execute_script("return arguments[0].naturalWidth", img) for img in images]
        assert all(w > 100 for w in widths), widths  # every embedded PNG decoded
        assert not driver.find_elements(By.ID, "simulated")  # real data: no simulated label anywhere
        assert "SIMULATED" not in driver.find_element(By.TAG_NAME, "body").text
        assert driver.find_element(By.ID, "claims").is_displayed()
        shot = report_dir / "screenshot.png"
        assert driver.save_screenshot(str(shot))
        assert shot.read_bytes()[:4] == b"\x89PNG"
        # The simulated folder: a visible label at the top, and every figure's caption says so.
        driver.get((simulated_report_dir / "index.html").resolve().as_uri())
        label = driver.find_element(By.ID, "simulated")
        assert label.is_displayed() and "Simulated data" in label.text and "42" in label.text
        top = driver.find_element(By.ID, "plain-words").text
        assert "Table 1" in top and "tuned" in top
        captions = [c.text for c in driver.find_elements(By.TAG_NAME, "figcaption")]
        assert captions and all(c.startswith("Simulated data.") for c in captions)
        labelled = driver.execute_script(
            "return document.querySelector('#simulated').getBoundingClientRect().top "
            "< document.querySelector('#glance').getBoundingClientRect().top")
        assert labelled  # the label comes before the results
    finally:
        driver.quit()


def test_models_failing_their_controls_are_flagged_in_the_tables(report_dir):
    controls = pd.read_csv(report_dir / "controls.csv")
    html = (report_dir / "index.html").read_text()
    parser = _Tables()
    parser.feed(html)
    for row in controls.itertuples():
        title = f"Root mean squared error (RMSE), {row.pad} pad, {row.cv.upper()}"
        title += "" if row.model == "pls" else f", {row.model} model"  # the paper's titles for its PLS
        header = {c[0].removesuffix(" †"): c[0].endswith("†") for c in parser.tables[title][0]}
        from roughsense.report.paper_tables import CONDITION_TITLES

        assert header[CONDITION_TITLES[row.condition]] == (not row.passes), (title, row.condition)


def test_report_leads_with_surfaces_never_seen(report_dir):
    """The section a user needs comes before the paper's LOO tables, with the analysis's numbers in it."""
    html = (report_dir / "index.html").read_text()
    body = html.split("</nav>", 1)[1]
    start = body.index('<h2 id="unseen">Surfaces held out of training (a grating, a period, a shape)</h2>')
    assert start < body.index('id="glance"') < body.index('id="results-loo"')
    assert start < body.index("Perceived and predicted roughness, smooth pad, LOO (mean ± SD)")
    section = body[start: body.index('id="glance"')]
    assert 'data-name="unseen_surfaces.png"' in section
    assert "user data" in section and "digital twin" not in section  # a real study: no twin caveat
    rows = _rows(html, "A grating left out of training: nested leave-one-specimen-out, per model, pad and condition")
    assert len(rows) == len(family_names()) * 2 * 4
    controls = pd.read_csv(report_dir / "controls.csv").query("cv == 'loso'").set_index(["model", "pad", "condition"])
    loso = pd.read_csv(report_dir / "results_loso.csv")
    from roughsense.model.registry import registry

    names = {family.title: family.name for family in registry()}
    for row in rows:
        model, pad, condition = names[row["Model"][0]], row["Pad"][0], row["Condition"][0]
        mine = loso[(loso.model == model) & (loso.pad == pad) & (loso.condition == condition)]
        assert row["Mean RMSE"][0] == f"{mine['rmse'].mean():.3f}"
        control = controls.loc[(model, pad, condition)]
        assert row["Permutation p"][0] == permutation_p_text(control["permutation_p"], control["n_permutations"])
        assert row["Controls"][0].startswith("passes") == bool(control["passes"])
        above = float(row["Mean RMSE"][0]) >= float(row["Training mean RMSE"][0])
        assert ("per-specimen RMSE" in row["Controls"][0]) == (bool(control["passes"]) and above)
    # The paper's tables keep the paper's PLS; the peak law's are labelled as its own.
    assert "Root mean squared error (RMSE), smooth pad, LOO, peak-law model" in html
    peak = _table(html, "Root mean squared error (RMSE), fingerprint pad, LOO, peak-law model")
    assert all(cells[c][1] == "" for cells in peak.values() for c in cells)  # no paper values beside the law


def test_unseen_section_labels_the_twin_and_built_in_agreement(simulated_report_dir, tmp_path, quick_figures):
    simulated = (simulated_report_dir / "index.html").read_text()
    section = simulated.split('<h2 id="unseen">', 1)[1].split('id="glance"', 1)[0]
    assert "digital twin" in section and "held out of" in section and "real images" in section
    assert "partly built in" not in section
    study, features = synthetic_study(repetitions=2, seed=6, pads=("smooth",))
    study.extra = {"simulation": {"seed": 5, "ratings_from": "physics"}}
    analysis = analyse_study(study, features=features, max_components=1, conditions=("1N",), n_permutations=0)
    write_report(analysis, tmp_path / "physics")
    physics = (tmp_path / "physics" / "index.html").read_text()
    section = physics.split('<h2 id="unseen">', 1)[1].split('id="glance"', 1)[0]
    assert "ratings_from = physics" in section and "partly built in" in section


def test_a_permutation_p_is_never_0_and_names_its_shufflings():
    assert permutation_p_text(0.005, 199) == "≤ 0.005 (199 shufflings)"
    assert permutation_p_text(1 / 2000, 1999) == "≤ 0.0005 (1999 shufflings)"  # not "0.000"
    assert permutation_p_text(0.02, 199) == "0.020" and permutation_p_text(0.02, 199, ".2g") == "0.02"
    assert permutation_p_text(0.5, 0) == "—"


def test_control_text_names_the_pooled_training_mean_and_a_pass_on_pooled_rmse_only():
    failing = {"beats_null": False, "beats_permutation": False, "n_permutations": 199, "permutation_p": 0.13,
               "rmse": 0.462, "null_rmse": 0.461}
    assert control_text(failing) == ("† pooled RMSE 0.462 not below the training mean's 0.461; no better than "
                                     "shuffled targets (p = 0.13)")
    passing = {"beats_null": True, "beats_permutation": True, "n_permutations": 199, "permutation_p": 0.005,
               "rmse": 0.438, "null_rmse": 0.461}
    assert control_text(passing) == "passes (p ≤ 0.005, none of 199 shufflings as good)"
    assert control_text(passing, mean_rmse=0.30, null_mean_rmse=0.354) == "passes (p ≤ 0.005, none of 199 shufflings as good)"
    assert control_text(passing, mean_rmse=0.365, null_mean_rmse=0.354) == (
        "passes (p ≤ 0.005, none of 199 shufflings as good), on pooled RMSE only: its mean per-specimen RMSE 0.365 is not below "
        "the training mean's 0.354")


@pytest.mark.parametrize("figure_format", ["svg", "pdf"])
def test_figures_in_a_vector_format_are_written_and_shown(tmp_path, figure_format, smooth_simulated_analysis):
    """--figure-format svg embeds the SVGs; pdf writes PDFs, shows a PNG of each and links the PDF."""
    from roughsense.report import FigureStyle
    from roughsense.report.html import report_owned

    analysis = smooth_simulated_analysis
    out = tmp_path / "report"
    write_report(analysis, out, style=FigureStyle(figure_format, 60))
    drawn = sorted(p.name for p in out.iterdir() if p.suffix in (".png", ".svg", ".pdf"))
    assert drawn and all(name.endswith(f".{figure_format}") for name in drawn)
    assert all(report_owned(Path(name)) for name in drawn)
    html = (out / "index.html").read_text()
    shown = "image/svg+xml" if figure_format == "svg" else "image/png"
    assert html.count(f'src="data:{shown};base64,') == len(drawn)
    assert all(f'<a href="{name}">{name}</a>' in html for name in drawn)
    if figure_format == "svg":
        assert all("SIMULATED DATA (seed 42)" in (out / name).read_text() for name in drawn)  # the stamp, as text
    first = {name: (out / name).read_bytes() for name in drawn}
    write_report(analysis, out, style=FigureStyle(figure_format, 60), force=True)
    assert {name: (out / name).read_bytes() for name in drawn} == first  # reruns give the same bytes


def test_the_simulated_stamp_sits_above_every_axes_and_component_ticks_are_whole():
    """The stamp covered axis labels in a corner; it now sits above the top axes. Component counts tick by 1s."""
    import matplotlib.pyplot as plt

    from roughsense.report import figures

    fig, ax = plt.subplots()
    ax.plot([1, 2, 3], [1, 2, 3])
    ax.set_xlabel("x label")
    ax.set_title("title")
    fig.tight_layout()
    stamp = figures.mark_simulated(fig, figure_stamp(Provenance("simulated", seed=0))).texts[-1]
    renderer = fig.canvas.get_renderer()
    box = stamp.get_window_extent(renderer)
    for artist in (ax, ax.xaxis.label, ax.yaxis.label, ax.title, *ax.get_xticklabels(), *ax.get_yticklabels()):
        assert not box.overlaps(artist.get_window_extent(renderer)), artist
    assert fig.bbox.contains(box.x0, box.y0) and fig.bbox.contains(box.x1, box.y1)  # on the canvas: drawn once
    plt.close(fig)
    cv = pd.DataFrame({"pad": "smooth", "cv": "loo", "condition": "1N", "n_components": [0, 1, 2, 3],
                       "rmse": [0.5, 0.3, 0.25, 0.26]})
    chosen = pd.DataFrame({"pad": ["smooth"], "condition": ["1N"], "cv": ["loo"], "best_n_components": [2]})
    fig = figures.cv_curves_figure(cv, chosen)
    fig.canvas.draw()
    ticks = [t for t in fig.axes[0].get_xticks() if fig.axes[0].get_xlim()[0] <= t <= fig.axes[0].get_xlim()[1]]
    assert ticks and all(float(t).is_integer() for t in ticks)
    plt.close(fig)


def test_the_stamp_grows_the_figure_and_keeps_every_axes_size_in_inches():
    import matplotlib.pyplot as plt

    from roughsense.report import figures

    fig, axes = plt.subplots(2, 2, figsize=(6.0, 4.0))
    fig.tight_layout()

    def boxes_in():  # each axes' box in inches from the figure's bottom left
        return [np.array(ax.get_position().bounds) * np.tile(fig.get_size_inches(), 2) for ax in axes.flat]

    before = boxes_in()
    figures.mark_simulated(fig, figure_stamp(Provenance("simulated", seed=0)))
    grown = fig.get_size_inches()[1] - 4.0
    assert 0.1 < grown < 0.6 and fig.get_size_inches()[0] == 6.0
    assert np.allclose(before, boxes_in())
    plt.close(fig)


def test_a_png_is_trimmed_to_its_ink_and_a_figure_drawn_past_its_edge_is_kept_whole():
    """PNGs are drawn once and trimmed by their pixels; ink at the canvas's edge may be cut, so such a figure is
    saved through matplotlib's tight box, which grows past the canvas to hold it."""
    import io

    import matplotlib.pyplot as plt
    from PIL import Image

    from roughsense.report import figures

    def size(fig) -> tuple[int, int]:
        return Image.open(io.BytesIO(figures.figure_bytes(fig, "png", dpi=100))).size

    fig, ax = plt.subplots(figsize=(4.0, 3.0))
    ax.plot([0, 1], [0, 1])
    fig.tight_layout()
    width, height = size(fig)
    assert width < 400 and height < 300  # tight_layout's margins trimmed to the pad
    fig, ax = plt.subplots(figsize=(4.0, 3.0))
    ax.plot([0, 1], [0, 1])
    fig.text(0.9, 0.5, "a label that runs past the right edge")
    width, _ = size(fig)
    assert width > 400 + 100  # the whole label is in the file


def test_the_cli_figure_options_match_the_report():
    """--dpi's default is the report's: both read roughsense.defaults, neither keeps a copy."""
    import inspect

    from roughsense import defaults
    from roughsense.cli import _common
    from roughsense.report import figures, html

    assert inspect.signature(figures.figure_bytes).parameters["dpi"].default == defaults.DPI
    assert html.FigureStyle().dpi == defaults.DPI
    assert not {"FIGURE_FORMATS", "DEFAULT_DPI"} & (set(vars(_common)) | set(vars(figures)))


@pytest.mark.browser
def test_the_first_screen_answers(report_dir, simulated_report_dir):
    """Issue 30: at 1400 x 900 px the top of the page says which model to use for new surfaces, its error against the
    training mean with its interval's coverage, where it passes its controls and how far to trust it; then the
    contents. The per-specimen tables are collapsed (the page's height is what a reader scrolls)."""
    from selenium.webdriver.common.by import By

    driver = _headless_chromium("1400,900")
    try:
        for folder, simulated in ((report_dir, False), (simulated_report_dir, True)):
            driver.get((folder / "index.html").resolve().as_uri())
            answer = driver.find_element(By.ID, "answer")
            bottom = driver.execute_script("const r = arguments[0].getBoundingClientRect(); return r.bottom", answer)
            assert bottom <= 900, bottom  # the whole answer on the first screen
            text = answer.text
            assert "training mean" in text and "passes its controls" in text and "How far to trust it" in text
            assert ("SIMULATED" in text) == simulated
            nav = driver.find_element(By.TAG_NAME, "nav")
            assert driver.execute_script("return arguments[0].getBoundingClientRect().top", nav) > bottom
            collapsed = driver.find_elements(By.CSS_SELECTOR, "details.table:not([open])")
            assert len(collapsed) >= 4 and not collapsed[0].find_element(By.TAG_NAME, "table").is_displayed()
            height = driver.execute_script("return document.documentElement.scrollHeight")
            assert height > 900
    finally:
        driver.quit()


def test_the_held_out_table_shows_every_scheme_with_the_csvs_numbers(report_dir):
    """Issue 35: the report says what each scheme held out, and its cells are held_out.csv's numbers."""
    from roughsense.analysis.held_out import SCHEME_WORDS

    html = (report_dir / "index.html").read_text()
    held = pd.read_csv(report_dir / "held_out.csv")
    rows = _rows(html, "Held out of training: a grating, a period, a shape")
    assert len(rows) == len(held) == len(family_names()) * 2 * 4 * 4  # models x pads x conditions x (grating, period, each shape)
    for row, (_, expected) in zip(rows, held.iterrows()):
        assert row["Held out"][0] == SCHEME_WORDS[expected.scheme] + (
            f" ({expected.n_folds} folds)" if expected.held_out == "all" else f": {expected.held_out}")
        assert row["Mean RMSE"][0] == f"{expected.rmse:.3f}" and row["Bias"][0] == f"{expected.bias:+.3f}"
        if pd.notna(expected.log_bias_rectangular):
            assert f"rectangular {expected.log_bias_rectangular:+.2f}" in row["Log bias by shape"][0]
        assert row["Controls"][0].startswith("passes") == bool(expected.passes)
    assert "never seen" not in html.split("</nav>", 1)[0]  # the first screen says what was held out
    presses = pd.read_csv(report_dir / "presses.csv")
    rows = _rows(html, "Presses per surface: the peak law's error on a grating left out of training")
    assert len(rows) == 2 * 4 and set(presses["model"]) == {"peak-law"}  # pads x conditions, the law's
    first = presses[(presses.pad == rows[0]["Pad"][0]) & (presses.condition == rows[0]["Condition"][0])]
    assert rows[0]["1 press"][0] == f"{first.set_index('n_presses').loc[1, 'rmse']:.3f}"
    assert (report_dir / "presses_per_surface.png").is_file()


def test_a_pass_on_pooled_rmse_alone_is_not_counted_as_a_pass():
    """Issue 35: the first screen's count leaves out a pass whose mean per-specimen RMSE is above the training mean's."""
    from types import SimpleNamespace

    from roughsense.report.answer import answer_lines

    unseen = pd.DataFrame({"model": ["pls", "pls"], "pad": ["smooth", "fingerprint"], "condition": ["combined"] * 2,
                           "rmse": [0.357, 0.30], "null_rmse": [0.333, 0.333], "passes": [True, True],
                           "n_permutations": [199, 199], "pi90_coverage_trials": [0.9, 0.9]})
    analysis = SimpleNamespace(fit_default="peak-law", unseen=unseen, held_out=pd.DataFrame(), provenance=Provenance(),
                               headline_condition=headline_condition(unseen["condition"]), evidence="")
    text = " ".join(answer_lines(analysis))
    assert "passes in 1 of 2, and in smooth combined on pooled RMSE only" in text
    from roughsense.report.answer import which_model_line

    assert "pls passes in 1 of 2 (and in 1 on pooled RMSE only)" in which_model_line(unseen)  # the terminal, too


def test_the_first_screen_table_says_what_was_held_out_and_counts_no_pooled_only_pass():
    """Issue 35: the answer is a small table per model and held-out scheme; a LOSO pass whose mean per-specimen RMSE
    is not below the training mean's reads "pooled RMSE only"; the jackknife+ interval is quoted where it exists."""
    from types import SimpleNamespace

    from roughsense.report.answer import answer_table

    held = pd.DataFrame({"model": ["pls", "peak-law", "peak-law", "peak-law"], "pad": ["smooth"] * 4,
                         "condition": ["combined"] * 4, "scheme": ["specimen", "specimen", "period", "shape"],
                         "held_out": ["all", "all", "all", "circular"], "rmse": [0.357, 0.16, 0.19, 0.33],
                         "null_rmse": [0.333, 0.33, 0.35, 0.42], "passes": [True] * 4, "n_permutations": [199] * 4,
                         "bias": [0.0, 0.0, 0.01, -0.33], "flagged_share": [0.0, 0.0, 0.29, 1.0]})
    held = pd.concat([held, held.iloc[[3]].assign(held_out="rectangular", bias=0.31, flagged_share=0.03)])
    presses = pd.DataFrame({"model": "peak-law", "pad": "smooth", "condition": "combined", "n_presses": [1, 3, 10],
                            "rmse": [0.30, 0.20, 0.16], "null_rmse": 0.33})
    unseen = pd.DataFrame({"model": ["pls", "peak-law"], "pad": ["smooth"] * 2, "condition": ["combined"] * 2,
                           "passes": [True, True], "jackknife_plus_coverage": [float("nan"), 13 / 14],
                           "jackknife_plus_median_factor": [float("nan"), 1.72], "jackknife_plus_specimens": [0, 14],
                           "jackknife_plus_missed": ["", "C2"]})
    needed = presses_needed_by_curve(presses)  # as analyse_study computes it once
    table = answer_table(SimpleNamespace(
        fit_default="peak-law", held_out=held, unseen=unseen, presses=presses, presses_needed=needed,
                                         headline_condition="combined"))
    assert table["rows"] == [
        ["PLS (the paper's model)", "a grating left out of training", "0.36 vs 0.33, pooled RMSE only"],
        ["peak law", "a grating left out of training",
         "0.16 vs 0.33, passes; 90 % surface interval held 13 of 14 specimens (misses C2), x/÷ 1.72; needs 3 presses "
         "per surface"],
        ["peak law", "a period left out (both shapes)", "0.19 vs 0.35, passes"],
        ["peak law", "a shape left out (fitted on the other): circular",
         "0.33 vs 0.42, passes, bias -0.33, 100% of presses flagged"],
        ["peak law", "a shape left out (fitted on the other): rectangular",  # a large bias nobody is warned of
         "0.33 vs 0.42, passes, bias +0.31, 3% of presses flagged: biased, mostly unflagged"]]

    # too few specimens: the jackknife+ has no finite width, and an infinite interval "held 100%" says nothing
    unseen["jackknife_plus_coverage"] = [float("nan"), 1.0]
    unseen["jackknife_plus_median_factor"] = [float("nan"), float("inf")]
    table = answer_table(SimpleNamespace(
        fit_default="peak-law", held_out=held, unseen=unseen, presses=presses, presses_needed=needed,
                                         headline_condition="combined"))
    assert table["rows"][1][2] == ("0.16 vs 0.33, passes; no 90 % surface interval (too few specimens); needs 3 "
                                   "presses per surface")
    from roughsense.report.unseen_tables import _jackknife_text

    row = {"jackknife_plus_coverage": 1.0, "jackknife_plus_median_factor": float("inf"), "jackknife_plus_misses": ""}
    assert _jackknife_text(row) == "none (too few specimens)"
    assert _jackknife_text({**row, "jackknife_plus_median_factor": 1.5, "jackknife_plus_misses": "R2 0.42 below"}) \
        == "100%, x/÷ 1.50; misses R2 0.42 below"


def test_the_first_screen_compares_the_paper_model_the_default_and_the_recommended_one():
    """However many families are registered, the first screen's table holds the paper's model, fit's default and
    the one recommended; a family that passes where the default fails is recommended, and shown."""
    from types import SimpleNamespace

    from roughsense.report.answer import answer_table, first_screen_models

    held = pd.DataFrame({"model": ["pls", "peak-law", "groove"], "pad": ["smooth"] * 3, "condition": ["combined"] * 3,
                         "scheme": ["specimen"] * 3, "held_out": ["all"] * 3, "rmse": [0.3, 0.2, 0.1],
                         "null_rmse": [0.33] * 3, "passes": [False, True, False], "n_permutations": [199] * 3,
                         "bias": [0.0] * 3, "flagged_share": [0.0] * 3})
    unseen = pd.DataFrame({"model": ["pls", "peak-law", "groove"], "pad": ["smooth"] * 3,
                           "condition": ["combined"] * 3, "passes": [False, True, False]})
    analysis = SimpleNamespace(fit_default="peak-law", held_out=held, unseen=unseen, presses_needed={},
                               headline_condition="combined")
    assert first_screen_models(unseen) == ("pls", "peak-law")
    assert [row[0] for row in answer_table(analysis)["rows"]] == ["PLS (the paper's model)", "peak law"]
    unseen["passes"] = held["passes"] = [False, False, True]  # only the groove model passes: it is the answer
    assert first_screen_models(unseen) == ("pls", "peak-law", "groove")
    assert [row[0] for row in answer_table(analysis)["rows"]][-1] == "groove model"


def test_figures_drawn_in_worker_processes_give_the_same_files(tmp_path, simulated_analysis, simulated_report_dir):
    """Two processes drawing the figures write byte for byte the report one process writes, every figure once."""
    write_report(simulated_analysis, tmp_path / "two", meta=SIMULATED_META, n_jobs=2)
    from roughsense.report.html import report_owned

    one = {p.name: p.read_bytes() for p in simulated_report_dir.iterdir()}  # the module's, drawn in one process
    two = {p.name: p.read_bytes() for p in (tmp_path / "two").iterdir()}
    assert one == two
    assert [name for name in one if not report_owned(Path(name))] == []  # --force replaces every file it wrote
    shown = re.findall(r'data-name="([^"]+)"', one["index.html"].decode())
    assert sorted(shown) == sorted(name for name in one if name.endswith(".png"))  # none drawn that is not shown
    assert len(shown) == len(set(shown))


def test_the_method_section_gives_the_peak_law_its_terms_of_today(report_dir):
    """Issue 46: the method said log(roughness) = b0 + b1 log(peak frequency) + b2 log(peak amplitude), "and how
    high": today's law has no peak-height term. It now reads the registry's description, as fit --model's help does."""
    import html as html_text

    from roughsense.model.registry import PEAK_LAW, family

    page = (report_dir / "index.html").read_text()
    method = html_text.unescape(re.sub(r"\s+", " ", page[page.index('id="method"'):page.index('<dl class="meta">',
                                                                                           page.index('id="method"'))]))
    assert f"{family(PEAK_LAW).description}. In logs, log(roughness)" in method and "b3 log(A(2 f0) / A(f0))" in method
    assert "peak amplitude)" not in method and "how high" not in method and "b2 log" not in method


def test_the_first_screens_surface_interval_is_one_count_of_specimens_naming_those_it_misses(simulated_analysis):
    """Issue 46: "90 % surface interval held 93%" was one count, 13 of 14 specimens: the first screen now says the
    count and names the specimens missed, read from the nested jackknife+ check itself."""
    from roughsense.report.answer import answer_table

    analysis = simulated_analysis
    table = answer_table(analysis)
    condition = analysis.headline_condition
    pads = [c.split(" pad:")[0] for c in table["columns"][2:]]
    row = next(r for r in table["rows"] if r[0] == "peak law" and r[1] == "a grating left out of training")
    for pad, cell in zip(pads, row[2:]):
        check = analysis.condition_fit(pad, condition, "loso", "peak-law").interval_check
        missed = list(check.loc[~check["covered"], "specimen"])
        held = f"held {len(check) - len(missed)} of {len(check)} specimens"
        assert (f"{held} (misses {', '.join(missed)}), x/÷" in cell) if missed else f"{held}, x/÷" in cell, cell


def test_presses_needed_say_what_a_press_is_in_the_combined_condition():
    """Issue 46: in the combined condition a press is one mount read at three forces, not three presses: the presses
    table, its figure's caption and predict's line say so; a single force's say nothing more."""
    from roughsense.cli.predict import few_presses_line
    from roughsense.report.presses import presses_table

    curve = pd.DataFrame({"model": "peak-law", "pad": "smooth", "n_presses": [1, 3], "rmse": [0.3, 0.2],
                          "null_rmse": 0.33})
    combined = presses_table(curve.assign(condition="combined"), {})
    single = presses_table(curve.assign(condition="2N"), {})
    assert "In the combined condition, a press is one mount read at 1, 2 and 3 N." in combined["caption"]
    assert "mount" not in single["caption"]
    training = {"condition": "combined", "presses": {"needed": 3, "null_rmse": 0.33, "rmse_by_presses": {"1": 0.35}}}
    from types import SimpleNamespace

    from roughsense.report.answer import answer_lines

    unseen = pd.DataFrame({"model": ["peak-law"], "pad": ["smooth"], "condition": ["combined"], "rmse": [0.2],
                           "null_rmse": [0.33], "passes": [True], "n_permutations": [199],
                           "pi90_coverage_trials": [0.9]})
    first = answer_lines(SimpleNamespace(fit_default="peak-law", unseen=unseen, provenance=Provenance(),
                                         headline_condition="combined", evidence=""))[0]
    assert "(combined, where a press is one mount read at 1, 2 and 3 N; mean per-specimen RMSE" in first
    assert "press each surface 3 times (--same-surface or --study groups them; a press is one mount read at 1, 2 and " \
           "3 N)" in few_presses_line(training, None, 2)
    assert "mount" not in few_presses_line({**training, "condition": "2N"}, None, 2)


def test_a_new_surface_is_one_the_studys_evidence_covers(simulated_analysis):
    """Issue 46: the first screen, the section on surfaces held out and the console said "a new surface" as if any
    would do; they now name the surfaces the evidence covers, from the study's own rated specimens."""
    from roughsense.report.answer import answer_lines, console_lines
    from roughsense.report.html import unseen_words

    analysis = simulated_analysis
    shapes = {analysis.shapes[s] for s in analysis.perceived["specimen"]}
    assert analysis.evidence.startswith(f"the study's {len(analysis.perceived)} specimens, ")
    assert all(shape in analysis.evidence for shape in shapes) and "gratings of 7 periods from 2 to 5 mm" in analysis.evidence
    said = f"The evidence covers surfaces like {analysis.evidence}."
    assert answer_lines(analysis)[-1].endswith(said) and said in " ".join(unseen_words(analysis))
    assert any(said in line for line in console_lines(analysis))
