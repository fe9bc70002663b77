"""The report folder: files, schemas, the paper's values beside ours, and a real browser rendering it."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import pandas as pd
import pytest

from roughsense import reference
from roughsense.errors import OutputExistsError
from roughsense.evaluation import analyse_study
from roughsense.report import write_report

from .test_evaluation import synthetic_study


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory):
    study, features = synthetic_study(repetitions=4, seed=3)
    analysis = analyse_study(study, features=features, max_components=6)
    out = tmp_path_factory.mktemp("report") / "report"
    write_report(analysis, out, meta={"source": "synthetic test study"})
    return out


def test_report_files_and_schemas(report_dir):
    names = {p.name for p in report_dir.iterdir()}
    assert {"index.html", "results.csv", "results_loso.csv", "cv.csv", "tests.csv"} <= names
    assert {"cv_curves.png", "spectra_smooth.png", "ovl_sd_fingerprint.png", "predicted_vs_perceived_loo.png"} <= names
    paper_columns = list(reference.paper_results().columns)
    assert list(pd.read_csv(report_dir / "results.csv").columns) == paper_columns
    assert list(pd.read_csv(report_dir / "results_loso.csv").columns) == paper_columns
    cv = pd.read_csv(report_dir / "cv.csv")
    assert list(cv.columns) == ["pad", "condition", "cv", "n_components", "rmse"]
    assert set(cv["cv"]) == {"loo", "loso"}
    assert list(pd.read_csv(report_dir / "tests.csv").columns[:4]) == ["comparison", "statistic", "p", "p_adjusted"]
    for png in report_dir.glob("*.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_report_shows_paper_values_beside_ours(report_dir):
    html = (report_dir / "index.html").read_text()
    # Table 3, fingerprint R2 at 1 N: RMSE 0.49; Table 1, C5 perceived 1.72 ± 0.64; LOO choice of 12 components.
    assert '<span class="paper">0.49</span>' in html
    assert '<span class="paper">1.72 ± 0.64</span>' in html
    assert '<span class="paper">12</span>' in html
    assert html.count("<table>") >= 2 + 2 * 2 * 3 + 1  # glance, components, 2 CV x 2 pads x 3, tests
    assert "src=\"http" not in html and "href=\"http" not in html  # self-contained, offline


def test_report_refuses_a_non_empty_folder_without_force(report_dir, tmp_path):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    study, features = synthetic_study(repetitions=2, seed=4)
    analysis = analyse_study(study, features=features, max_components=2, cv_schemes=("loo",))
    with pytest.raises(OutputExistsError):
        write_report(analysis, mine)
    write_report(analysis, mine, force=True)
    assert (mine / "notes.txt").read_text() == "keep me"
    assert (mine / "index.html").is_file() and not (mine / "results_loso.csv").exists()


def _chromium() -> tuple[str, str] | None:
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    return (browser, driver) if browser and driver else None


@pytest.mark.browser
def test_report_renders_in_headless_chromium(report_dir):
    found = _chromium()
    if found is None:
        if os.environ.get("CI"):
            pytest.fail("CI must install Debian's chromium and chromium-driver (see .ci/run)")
        pytest.skip("chromium/chromedriver not installed")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By

    browser, driver_path = found
    options = webdriver.ChromeOptions()
    options.binary_location = browser
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--window-size=1280,2000"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(executable_path=driver_path), options=options)
    try:
        driver.get((report_dir / "index.html").resolve().as_uri())
        assert "roughsense report" in driver.title
        tables = driver.find_elements(By.TAG_NAME, "table")
        assert len(tables) >= 15
        first_rows = tables[0].find_elements(By.CSS_SELECTOR, "tbody tr")
        assert len(first_rows) == 8  # 2 pads x 4 conditions
        images = driver.find_elements(By.CSS_SELECTOR, "figure img")
        assert len(images) >= 6
        widths = [driver.execute_script("return arguments[0].naturalWidth", img) for img in images]
        assert all(w > 100 for w in widths), widths  # every embedded PNG decoded
        shot = report_dir / "screenshot.png"
        assert driver.save_screenshot(str(shot))
        assert shot.read_bytes()[:4] == b"\x89PNG"
    finally:
        driver.quit()
