"""roughsense explore: sweep files, cells equal to the study path, the Parquet store, Dask (local and remote), report."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from roughsense.analysis import dataset
from roughsense.analysis.dataset import study_features
from roughsense.analysis.study_analysis import analyse_study
from roughsense.errors import ConfigError, OutputExistsError
from roughsense.explore import cell as explore_cell
from roughsense.explore.runner import run_sweep
from roughsense.explore.store import ResultStore
from roughsense.explore.sweep import read_sweep
from roughsense.io.protocol import nominal_force_label
from roughsense.io.study import read_study
from roughsense.sensor.spectrum import SpatialSpectrum
from roughsense.sim import contact
from roughsense.sim import simulate as sim
from roughsense.sim.config import SimulationConfig
from roughsense.sim.frames import render_trial, trial_line
from roughsense.sim.plan import plan_trials
from roughsense.sim.specimens import parse_specimen
from tests import explore_tasks

SPECIMENS = '["R2", "R3", "R4", "C3", "rect:1.5"]'
TINY = f"""
[sweep]
seeds = [0, 1]
repetitions = 2
specimens = {SPECIMENS}
image_size_px = [480, 160]
max_components = 4
[axes]
pad = ["smooth"]
"""


def _sweep_file(tmp_path: Path, text: str = TINY, name: str = "sweep.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# --------------------------------------------------------------------------- the simulator's fast paths


def test_rendered_rows_are_the_whole_frames_rows():
    config = SimulationConfig(pads=("fingerprint",), specimens=("R2", "C3"), repetitions=2, forces_n=(1.0, 3.0))
    pads, specimens = config.validate()
    trials = plan_trials(config, pads, specimens)
    assert any(t.mount.spots for t in trials)  # spots cross the window's edges too
    for trial in trials:
        full, fraction = render_trial(trial)
        height = trial.camera.frame_height_px
        for rows in ((0, 1), (height // 2 - 5, height // 2 + 10), (height - 20, height)):
            part, same = render_trial(trial, rows=rows)
            assert np.array_equal(part, full[rows[0]:rows[1]]) and same == fraction


def test_warm_started_contact_equals_the_cold_solution():
    modulus = 0.17e6 / (1 - 0.49**2)
    for spec, iterations_at_most in (("R3", 5), ("C3", None), ("sin:1.2:0.2", None)):
        specimen = parse_specimen(spec)
        length, _ = contact.periodic_domain(specimen.period_mm, None)
        n = contact.grid_points(length)
        height = specimen.height_mm(np.arange(n) * length / n)
        first = contact.solve_periodic(height, length, 4000.0, modulus, tol=1e-6)
        for pressure in (3000.0, 4100.0, 5200.0):
            cold = contact.solve_periodic(height, length, pressure, modulus, tol=1e-6)
            warm = contact.solve_periodic(height, length, pressure, modulus, tol=1e-6,
                                          initial_pressure_pa=first.pressure_pa)
            # The same answer: gaps agree far below the optics' 20 um decay length.
            assert np.max(np.abs(warm.gap_mm - cold.gap_mm)) < 1e-6
            assert warm.pressure_pa.mean() == pytest.approx(pressure)
            if iterations_at_most:  # flat lands: the contact set does not move, a warm start is nearly free
                assert warm.iterations <= iterations_at_most < cold.iterations
        # Starting from the answer itself: nothing to do (and no division by the zero residual).
        again = contact.solve_periodic(height, length, 4000.0, modulus, tol=1e-6, initial_pressure_pa=first.pressure_pa)
        assert np.max(np.abs(again.gap_mm - first.gap_mm)) < 1e-6


def test_a_warm_start_that_cycles_restarts_cold(monkeypatch):
    config = SimulationConfig(pads=("smooth",), specimens=("C3",), repetitions=1, forces_n=(2.0,))
    pads, specimens = config.validate()
    trial = plan_trials(config, pads, specimens)[0]
    solve = contact.solve_periodic

    def cycling(*args, initial_pressure_pa=None, **kwargs):
        if initial_pressure_pa is not None:
            raise contact.ContactNotConverged("cycling")
        return solve(*args, **kwargs)

    monkeypatch.setattr(contact, "solve_periodic", cycling)
    warm: dict = {}
    line, fraction = trial_line(trial, warm=warm)
    assert warm  # solutions kept for the next trial
    cold_line, cold_fraction = trial_line(trial)
    assert np.array_equal(line, cold_line) and fraction == cold_fraction


# --------------------------------------------------------------------------- a cell is the study path in memory


@pytest.mark.slow
def test_cell_equals_simulate_then_study(tmp_path):
    sweep = read_sweep(_sweep_file(tmp_path, TINY.replace('pad = ["smooth"]', 'pad = ["fingerprint"]')))
    cell = sweep.cells[0]
    # The study path: simulate a folder with the same design and analyse it with the same sensor crop.
    config = explore_cell.simulation_config(cell)
    sim.simulate_study(tmp_path / "study", config, jobs=1)
    study = read_study(tmp_path / "study", require_ratings=True)
    roi = explore_cell.sensor_roi(cell.width_px, cell.height_px)
    features = study_features(study, spectrum=SpatialSpectrum(px_per_mm=study.sensor.px_per_mm, roi=roi).fit())
    # Cold contact solves: the cell's spectra are bit-identical to the ones read back from the PNG files.
    cell_study, cold = explore_cell.cell_features(cell, warm_start=False)
    # One table: the cell's manifest is the folder's as read_study returns it (images by name: no files).
    folder = study.manifest.assign(image=study.manifest["image"].str.removeprefix("images/"))
    pd.testing.assert_frame_equal(cell_study.manifest, folder)
    as_read = cell_study.ratings.astype({"session": str}).reset_index(drop=True)  # the CSV keeps sessions as text
    pd.testing.assert_frame_equal(as_read, study.ratings.reset_index(drop=True), check_dtype=False)  # simulate's panel
    freq = dataset.frequency_columns(cold)
    ours = cold.set_index("image").loc[features["image"].str.removeprefix("images/")]
    assert np.array_equal(ours[freq].to_numpy(), features[freq].to_numpy())
    assert np.array_equal(ours["force_n"].to_numpy(), features["force_n"].to_numpy())
    # Warm-started solves move brightness by ~1e-5 at most: a rare 8-bit level, so spectra agree closely.
    _, warm = explore_cell.cell_features(cell)
    assert np.max(np.abs(warm[freq].to_numpy() - cold[freq].to_numpy())) < 1e-3 * np.max(cold[freq].to_numpy())
    # The rows: the study's own analysis of the folder, summarised per pad x condition x CV scheme.
    analysis = analyse_study(study, features=features, max_components=cell.max_components,
                             n_permutations=0, models=("pls",))  # a sweep without the model axis: the paper's PLS
    summary, per_specimen = explore_cell.cell_rows(cell)
    for fit in analysis.fits:
        row = summary[(summary.condition == fit.condition) & (summary.cv == fit.cv)].iloc[0]
        assert row["rmse"] == pytest.approx(fit.table["rmse"].mean(), rel=2e-2)
        assert row["cv_rmse"] == pytest.approx(fit.curve[fit.best], rel=2e-2)
    assert set(summary["condition"]) == {"1N", "2N", "3N", "combined"} and set(summary["cv"]) == {"loo", "loso"}
    assert set(summary["model"]) == set(per_specimen["model"]) == {"pls"}
    assert len(per_specimen) == 8 * 5 and per_specimen["ovl"].isna().sum() == 8  # R3 has no OVL


def test_a_design_in_memory_equals_its_simulated_folder_read_back(tmp_path):
    """explore.cell.design_features, cold, on the camera's full frame and both pads: the very table (manifest columns
    and spectra) and perceived roughness that simulate + read_study + study_features give (tests use it as a
    faster way to the same study)."""
    config = SimulationConfig(specimens=("R3", "C4", "rect:8"), forces_n=(1.0, 3.0), repetitions=1, seed=3)
    study = read_study(sim.simulate_study(tmp_path / "study", config, jobs=1), require_ratings=True)
    folder = study_features(study)
    memory_study, memory = explore_cell.design_features(config, warm_start=False)
    # design_features renders only the line's rows, so it carries no contact measures (they read the band above it)
    assert not set(dataset.contact_columns()) & set(memory.columns)
    read_back = folder.assign(image=folder["image"].str.removeprefix("images/"))
    pd.testing.assert_frame_equal(memory, read_back.drop(columns=dataset.contact_columns()))
    # asked for them (a family that reads the contact), it renders the band and reads each pad with its own ridges
    _, with_contact = explore_cell.design_features(config, warm_start=False, contact=True)
    pd.testing.assert_frame_equal(with_contact, read_back)
    pd.testing.assert_frame_equal(dataset.perceived_roughness(memory_study), dataset.perceived_roughness(study))
    assert (memory_study.pads, memory_study.pad_ridge_period_mm, memory_study.forces_n) == (
        study.pads, study.pad_ridge_period_mm, study.forces_n)


def test_a_cell_that_fits_a_contact_family_reads_the_contact_measures(tmp_path):
    """Without them a family that reads the contact would fit its training mean and flag every press, silently."""
    from dataclasses import replace

    cell = read_sweep(_sweep_file(tmp_path)).cells[0]
    _, plain = explore_cell.cell_features(cell)
    _, read = explore_cell.cell_features(replace(cell, models=("pls", "groove")))
    assert not set(dataset.contact_columns()) & set(plain.columns)
    assert read[dataset.contact_columns()[:2]].notna().any().all()  # land and groove widths read on the smooth pad
    freq = dataset.frequency_columns(plain)
    assert np.array_equal(read[freq].to_numpy(), plain[freq].to_numpy())  # the spectra are the same either way


def test_run_cell_records_a_failure_as_one_line(tmp_path, monkeypatch):
    cell = read_sweep(_sweep_file(tmp_path)).cells[0]

    def broken(_cell):
        raise ConfigError("pad 'smooth' on specimen 'R2' at 4000 Pa: the contact solver did not converge\nin time")

    monkeypatch.setattr(explore_cell, "cell_rows", broken)
    result = explore_cell.run_cell(cell)
    assert result["results"] is None and "\n" not in result["error"] and "did not converge in time" in result["error"]


# --------------------------------------------------------------------------- the sweep file


def test_sweep_grid_and_cell_ids(tmp_path):
    text = TINY.replace('pad = ["smooth"]', 'pad = ["smooth", "fingerprint"]\nfingerprint_period_mm = [1.0, 0.5]\n'
                        'forces_n = [[1, 2, 3], [2, 1]]')
    sweep = read_sweep(_sweep_file(tmp_path, text))
    # smooth ignores the fingerprint period: (1 + 2) pad designs x 2 force sets x 2 seeds
    assert len(sweep.cells) == 12 and len({c.id for c in sweep.cells}) == 12
    smooth = [c for c in sweep.cells if c.pad == "smooth"]
    assert all(c.fingerprint_period_mm is None for c in smooth) and {c.forces_n for c in smooth} == {(1, 2, 3), (1, 2)}
    # ids depend on content only: the same grid point in another file keeps its id (reruns find it finished)
    again = read_sweep(_sweep_file(tmp_path, "# a comment\n" + text, "other.toml"))
    assert [c.id for c in again.cells] == [c.id for c in sweep.cells]


@pytest.mark.parametrize("text, message", [
    (TINY + "colour = [1]\n", "unknown axis 'colour'"),
    (TINY.replace('pad = ["smooth"]', 'pad = ["smooth", "velvet"]'), "unknown value 'velvet'"),
    (TINY.replace('pad = ["smooth"]', "pad = []"), "the grid is empty"),
    (TINY.replace("seeds = [0, 1]", "seeds = []"), "seeds"),
    (TINY + "field_length_mm = [5.0]\n", "shorter than 10 mm"),
    (TINY.replace(SPECIMENS, '["R2", "R3", "blob:2"]'), "unknown specimen 'blob:2'"),
    (TINY.replace("[sweep]", "[sweep]\nratings_from = \"dreams\""), "unknown value 'dreams'"),
    ("[sweep\n", "is not valid TOML"),
    (TINY + 'model = ["pls", "ridge"]\n', "[axes] model must be one of pls, peak-law, groove, got 'ridge'"),
    (TINY.replace("[sweep]", '[sweep]\nmodel = "lasso"'), "[sweep] model must be one of pls, peak-law"),
    (TINY + 'model = "pls"\n', "[axes] model: expected a non-empty list"),
    (TINY + 'model = ["pls", "PLS"]\n', "[axes] model: a model is listed twice"),
])
def test_bad_sweep_files_are_one_line_exit_2(tmp_path, run_cli, text, message):
    path = _sweep_file(tmp_path, text)
    code, out, err = run_cli("explore", path, "--out", tmp_path / "out")
    assert code == 2 and message in err and str(path) in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_unreachable_scheduler_is_one_line_exit_2(tmp_path, run_cli):
    # How long the refusal takes is benchmarks/bench_refusals.py's to measure, not a test's.
    code, _, err = run_cli("explore", _sweep_file(tmp_path), "--out", tmp_path / "out", "--scheduler", "tcp://127.0.0.1:9")
    assert code == 2 and "cannot reach the Dask scheduler" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out" / "results").exists()


def test_a_folder_of_another_sweep_or_of_user_files_is_refused(tmp_path):
    first = read_sweep(_sweep_file(tmp_path))
    store = ResultStore(tmp_path / "out", first)
    store.prepare()
    (tmp_path / "out" / "results" / "cell-0123456789abcdef.parquet").write_bytes(b"stale")
    with pytest.raises(OutputExistsError, match="not cells of this sweep"):  # e.g. from an older roughsense
        ResultStore(tmp_path / "out", first).prepare()
    ResultStore(tmp_path / "out", first)  # the same sweep: resumes
    other = read_sweep(_sweep_file(tmp_path, TINY.replace("seeds = [0, 1]", "seeds = [5]"), "other.toml"))
    with pytest.raises(OutputExistsError, match="another sweep"):
        ResultStore(tmp_path / "out", other)
    forced = ResultStore(tmp_path / "out", other, force=True)
    assert forced.prepare() == ["0123456789abcdef"]  # the other sweep's cells go, with --force only
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    with pytest.raises(OutputExistsError, match="holds no sweep"):
        ResultStore(mine, first)
    ResultStore(mine, first, force=True).prepare()
    assert (mine / "notes.txt").read_text() == "keep"


def test_mean_interval_is_the_t_interval():
    from scipy import stats

    from roughsense.analysis.metrics import mean_interval

    values = [0.3, 0.5, 0.4, 0.6, np.nan]
    mean, half, n = mean_interval(values)
    low, high = stats.t.interval(0.95, 3, loc=np.mean(values[:4]), scale=stats.sem(values[:4]))
    assert (mean, n) == (pytest.approx(0.45), 4) and half == pytest.approx((high - low) / 2)
    assert np.isnan(mean_interval([0.2])[1]) and mean_interval([0.2])[:1] == (0.2,)
    assert np.isnan(mean_interval([])[0]) and mean_interval([])[2] == 0
    low, high = stats.t.interval(0.9, 3, loc=np.mean(values[:4]), scale=stats.sem(values[:4]))
    assert mean_interval(values, alpha=0.1)[1] == pytest.approx((high - low) / 2)


# --------------------------------------------------------------------------- on Dask


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    """The tiny sweep on a 2-worker LocalCluster, with a task that fails seed 1 on the worker."""
    tmp = tmp_path_factory.mktemp("explore")
    sweep = read_sweep(_sweep_file(tmp))
    outcome = run_sweep(sweep, tmp / "out", n_jobs=2, task=explore_tasks.fail_seed_one)
    return sweep, tmp / "out", outcome


@pytest.mark.slow
def test_local_cluster_run_records_failures_and_resumes(local_run):
    sweep, out, outcome = local_run
    assert (outcome.total, outcome.computed, len(outcome.failures)) == (2, 1, 1)
    failure = outcome.failures[0]
    assert failure["seed"] == 1 and failure["error"] == "RuntimeError: boom on the worker second line"
    assert pd.read_csv(out / "failures.csv")["error"].tolist() == [failure["error"]]
    results = pd.read_parquet(out / "results")
    assert len(results) == 4 * 2  # 1 cell x 1 pad x 4 conditions x 2 CV schemes
    assert {"cell", "seed", "pad", "condition", "cv", "n_components", "rmse", "ovl", "specimens"} <= set(results.columns)
    assert (out / "sweep.toml").read_bytes() == sweep.path.read_bytes()
    # Rerun: the finished cell is skipped (its file untouched), the failed one is computed now.
    done = out / "results" / f"cell-{results['cell'].iloc[0]}.parquet"
    stamp = done.stat().st_mtime_ns
    again = run_sweep(sweep, out, n_jobs=1)
    assert (again.skipped, again.computed, again.failures) == (1, 1, [])
    assert done.stat().st_mtime_ns == stamp and not (out / "failures.csv").exists()
    assert pd.read_parquet(out / "results")["seed"].nunique() == 2


#: Not a timing check: how long a Dask process may take to start or stop before the test fails instead of hanging
#: (a busy machine takes many times the usual second or two to import distributed).
HANG_GUARD_S = 300


def _written_address(scheduler_file: Path) -> str | None:
    """The address in the scheduler file, or None while the scheduler has not (wholly) written it yet."""
    try:
        return json.loads(scheduler_file.read_text())["address"]
    except (OSError, ValueError, KeyError, TypeError):
        return None


@pytest.mark.slow
def test_remote_scheduler_gives_the_same_numbers(local_run, tmp_path, run_cli):
    sweep, local_out, _ = local_run
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parents[2] / "src"), *sys.path])}
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    scheduler_file = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([*dask, "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(scheduler_file)], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + HANG_GUARD_S
        while (address := _written_address(scheduler_file)) is None:
            assert procs[0].poll() is None, "the Dask scheduler ended before it wrote its scheduler file"
            assert time.monotonic() < deadline, "the Dask scheduler never wrote its scheduler file"
            time.sleep(0.05)
        procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", "--nthreads", "1",
                                       "--no-dashboard", "--scheduler-file", str(scheduler_file)], env=env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        code, out, err = run_cli("explore", sweep.path, "--out", tmp_path / "remote", "--scheduler", address)
        assert code == 0, err
    finally:
        for proc in reversed(procs):
            proc.terminate()
            try:
                proc.wait(timeout=HANG_GUARD_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
    local = pd.read_parquet(local_out / "results").sort_values(["cell", "condition", "cv"]).reset_index(drop=True)
    remote = pd.read_parquet(tmp_path / "remote" / "results").sort_values(["cell", "condition", "cv"])
    assert set(remote["seed"]) == {cell.seed for cell in sweep.cells}  # every cell computed remotely
    # compared on the local run's cells: both once test_local_cluster_run_records_failures_and_resumes has resumed
    # it, only the one that did not fail when this test runs alone (-k, --lf) or first
    remote = remote[remote["cell"].isin(local["cell"])]
    pd.testing.assert_frame_equal(local, remote.reset_index(drop=True))
    html = (tmp_path / "remote" / "index.html").read_text()
    assert "Best design" in html and "Limits of the twin" in html and 'src="http' not in html


def _chromium():
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    return (browser, driver) if browser and driver else None


@pytest.mark.slow
@pytest.mark.browser
def test_explore_report_renders_in_headless_chromium(local_run):
    from roughsense.explore.write_report import write_explore_report

    sweep, out, _ = local_run
    index = write_explore_report(sweep, out)
    found = _chromium()
    if found is None:
        if os.environ.get("CI"):
            pytest.fail("CI must install Debian's chromium and chromium-driver (see .ci/run)")
        pytest.skip("chromium/chromedriver not installed")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By

    options = webdriver.ChromeOptions()
    options.binary_location = found[0]
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=1280,2000"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(executable_path=found[1]), options=options)
    try:
        driver.get(index.resolve().as_uri())
        assert "roughsense sweep" in driver.title
        headings = [h.text for h in driver.find_elements(By.TAG_NAME, "h2")]
        assert headings[:3] == ["Best design", "The paper's open questions", "Along each axis"]
        assert len(driver.find_elements(By.TAG_NAME, "table")) >= 2
        uncovered = driver.find_elements(By.CSS_SELECTOR, "p.uncovered")
        assert len(uncovered) >= 3  # this sweep answers none of the questions that need an axis
    finally:
        driver.quit()


def test_combined_condition_over_other_forces():
    from roughsense.analysis.dataset import condition_matrix

    rng = np.random.default_rng(0)
    rows = []
    for specimen in ("R2", "C3"):
        for repetition in (1, 2):
            for force in ("1N", "2N", "4N"):
                rows.append({"image": f"{specimen}_{force}_{repetition}", "pad": "smooth", "specimen": specimen,
                             "repetition": repetition, "condition": force,
                             "spectrum@0.1": rng.random(), "spectrum@0.2": rng.random()})
    features = pd.DataFrame(rows)
    X, meta = condition_matrix(features, "smooth", "combined", combined_forces=["1N", "4N"])
    single = {f: condition_matrix(features, "smooth", f)[0] for f in ("1N", "4N")}
    assert np.array_equal(X, np.hstack([single["1N"], single["4N"]]))
    assert list(meta.columns) == ["specimen", "repetition", "image_1N", "image_4N"]
    with pytest.raises(Exception, match="every trial needs 1N, 3N"):
        condition_matrix(features, "smooth", "combined", combined_forces=["1N", "3N"])


def test_physics_ratings_reach_the_cell(tmp_path):
    from roughsense.sim.panel import simulate_panel

    sweep = read_sweep(_sweep_file(tmp_path, TINY.replace("[sweep]", '[sweep]\nratings_from = "physics"')))
    cell = sweep.cells[0]
    config = explore_cell.simulation_config(cell)
    assert cell.ratings_from == "physics" and config.ratings_from == "physics"
    from roughsense.explore.cell_panel import panel_ratings
    from roughsense.io.ratings_file import validate_ratings

    specimens = config.validate()[1]
    ours = panel_ratings(specimens, cell.seed, ratings_from="physics")
    theirs = simulate_panel(specimens, cell.seed, spawn_key=(4,), ratings_from="physics")
    pd.testing.assert_frame_equal(ours, validate_ratings(theirs))  # checked as a ratings.csv would be
    assert not ours.equals(panel_ratings(specimens, cell.seed, ratings_from="paper"))


# --------------------------------------------------------------------------- the model axis

TWO_MODELS = TINY.replace("seeds = [0, 1]", "seeds = [0]") + 'model = ["pls", "peak-law"]\n'


def _old_id(cell) -> str:
    """A cell's id as computed before the model axis existed: the hash of its content, nothing else."""
    import dataclasses
    import hashlib

    content = {k: v for k, v in dataclasses.asdict(cell).items() if k not in ("id", "models")}
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()[:16]


def test_model_axis_keeps_old_ids_and_never_shares_one(tmp_path):
    plain = read_sweep(_sweep_file(tmp_path))
    assert all(c.models == ("pls",) and c.id == _old_id(c) for c in plain.cells)
    assert "model" not in plain.axes
    same = [read_sweep(_sweep_file(tmp_path, text, f"same{i}.toml")) for i, text in enumerate((
        TINY + 'model = ["pls"]\n', TINY.replace("[sweep]", '[sweep]\nmodel = "PLS"')))]
    for sweep in same:  # naming the paper's model explicitly is the same design
        assert [c.id for c in sweep.cells] == [c.id for c in plain.cells]
    both = read_sweep(_sweep_file(tmp_path, TINY + 'model = ["Peak-Law", "pls"]\n', "both.toml"))
    law = read_sweep(_sweep_file(tmp_path, TINY + 'model = ["peak-law"]\n', "law.toml"))
    assert both.models == ("pls", "peak-law") and both.axes["model"] == ["pls", "peak-law"]
    assert law.models == ("peak-law",) and len(both.cells) == len(law.cells) == len(plain.cells)  # one cell, all models
    ids = [c.id for s in (plain, both, law) for c in s.cells]
    assert len(set(ids)) == len(ids)


@pytest.fixture(scope="module")
def two_model_cell(tmp_path_factory):
    """One tiny cell fitted with both families, its study and features computed once."""
    tmp = tmp_path_factory.mktemp("models")
    sweep = read_sweep(_sweep_file(tmp, TWO_MODELS))
    cell = sweep.cells[0]
    study, features = explore_cell.cell_features(cell)
    patch = pytest.MonkeyPatch()
    patch.setattr(explore_cell, "cell_features", lambda _cell: (study, features))
    try:
        summary, per_specimen = explore_cell.cell_rows(cell)
    finally:
        patch.undo()
    return sweep, cell, study, features, summary, per_specimen


def test_model_axis_rows_equal_the_study_analysis_of_each_model(two_model_cell):
    sweep, cell, study, features, summary, per_specimen = two_model_cell
    assert set(summary["model"]) == set(per_specimen["model"]) == {"pls", "peak-law"}
    # Every pad x condition x CV scheme once per model.
    assert summary.groupby("model").size().to_dict() == {"pls": 4 * 2, "peak-law": 4 * 2}
    labels = [nominal_force_label(f) for f in study.forces_n]
    alone = analyse_study(study, features=features, max_components=cell.max_components,
                          conditions=[*labels, "combined"], cv_schemes=cell.cv, combined_forces=labels,
                          n_permutations=0, models=("peak-law",))
    law = summary[summary["model"] == "peak-law"].set_index(["condition", "cv"])
    for fit in alone.fits:
        row = law.loc[(fit.condition, fit.cv)]
        assert row["rmse"] == fit.table["rmse"].mean() and row["n_components"] == 1
        assert row["cv_rmse"] == fit.curve[1]
        mine = per_specimen[(per_specimen["model"] == "peak-law") & (per_specimen["condition"] == fit.condition)
                            & (per_specimen["cv"] == fit.cv)].set_index("specimen")
        theirs = fit.table.set_index("specimen")
        assert np.array_equal(mine.loc[theirs.index, "pred_mean"].to_numpy(), theirs["pred_mean"].to_numpy())


def test_model_axis_report_puts_the_families_side_by_side(two_model_cell, tmp_path):
    from roughsense.explore.write_report import SUMMARY_CSV, write_explore_report

    sweep, cell, *_, summary, per_specimen = two_model_cell
    store = ResultStore(tmp_path / "out", sweep)
    store.prepare()
    store.write_cell(summary, per_specimen, cell.id)
    assert list(pd.read_parquet(tmp_path / "out" / "results").columns)[-1] == "model"  # columns only added
    index = write_explore_report(sweep, tmp_path / "out")
    table = pd.read_csv(tmp_path / "out" / SUMMARY_CSV)
    assert table.columns[-1] == "model" and set(table["model"]) == {"pls", "peak-law"}
    for model in ("pls", "peak-law"):  # summary.csv: each model's row is that model's stored row
        stored = summary[(summary["model"] == model) & (summary["condition"] == "combined") & (summary["cv"] == "loso")]
        row = table[(table["model"] == model) & (table["condition"] == "combined") & (table["cv"] == "loso")]
        assert row["rmse"].iloc[0] == pytest.approx(stored["rmse"].iloc[0], rel=1e-5)
    html = index.read_text()
    assert "rmse (pls)" in html and "rmse (peak-law)" in html


def test_side_by_side_keeps_each_family_beside_the_other():
    from roughsense.explore.summary import side_by_side

    nan = float("nan")
    frame = pd.DataFrame({"pad": ["smooth", "smooth", "fingerprint", "fingerprint", "fingerprint"],
                          "fingerprint_period_mm": [nan, nan, 1.0, 1.0, 0.5], "cv": ["loso"] * 5,
                          "model": ["peak-law", "pls", "pls", "peak-law", "pls"],
                          "rmse": [0.2, 0.4, 0.5, 0.3, 0.6], "rmse_ci95": [0.01, 0.02, 0.03, 0.04, 0.05]})
    wide = side_by_side(frame, ["pad", "fingerprint_period_mm", "cv"])
    assert list(wide.columns[3:]) == ["rmse (pls)", "rmse (peak-law)", "rmse (pls)_ci95", "rmse (peak-law)_ci95"]
    assert wide["pad"].tolist() == ["smooth", "fingerprint", "fingerprint"]  # the designs in their first order
    assert wide["rmse (pls)"].tolist() == [0.4, 0.5, 0.6] and wide["rmse (peak-law)"].tolist()[:2] == [0.2, 0.3]
    assert np.isnan(wide["rmse (peak-law)"].iloc[2])  # a design one family lacks stays empty for it
    single = frame[frame["model"] == "pls"]
    assert side_by_side(single, ["pad", "fingerprint_period_mm", "cv"]) is single


# --------------------------------------------------------------------------- answers from paired intervals

def test_mde_80_is_the_noncentral_t_solution_statsmodels_gives():
    """The exact effect a two-sided paired t-test detects with the stated power, as statsmodels' TTestPower solves it."""
    from scipy import stats

    from roughsense.explore.paired import mde_80, paired_t_power

    power = pytest.importorskip("statsmodels.stats.power").TTestPower()
    cases = [(n, 0.05, 0.8) for n in (3, 4, 5, 6, 12, 30, 100)] + [
        (n, alpha, p) for n in (3, 4, 8, 20) for alpha, p in ((0.1, 0.5), (0.05, 0.95))] + [(5, 0.01, 0.9)]
    for n, alpha, p in cases:  # (statsmodels' own bracket fails for 3 or 4 pairs at alpha 0.01, power 0.9)
        exact = power.solve_power(nobs=n, alpha=alpha, power=p, alternative="two-sided")
        assert mde_80(1.0, n, alpha, p) == pytest.approx(exact, rel=2e-5)
        assert paired_t_power(mde_80(1.0, n, alpha, p), n, alpha) == pytest.approx(p, abs=1e-9)
    assert mde_80(0.05, 4) == pytest.approx(0.05 * mde_80(1.0, 4), rel=1e-12)  # in units of the differences' SD
    shortcut = (stats.t.ppf(0.975, 2) + stats.t.ppf(0.8, 2)) / np.sqrt(3)
    assert mde_80(1.0, 3) > 1.05 * shortcut  # the textbook shortcut understates it at 3 seeds
    assert mde_80(1.0, 2) > 10 and np.isnan(mde_80(0.1, 1)) and np.isnan(mde_80(np.nan, 4))
    with pytest.raises(ValueError, match="power"):
        mde_80(1.0, 4, power=1.0)


def _diffs(mean: float, half: float, n: int = 4) -> np.ndarray:
    """n per-seed differences whose t-interval is exactly mean ± half."""
    from scipy import stats

    shape = np.linspace(-1.0, 1.0, n)
    shape = shape / shape.std(ddof=1)
    return mean + shape * half * np.sqrt(n) / stats.t.ppf(0.975, n - 1)


@pytest.mark.parametrize("mean, half, metric, verdict, words", [
    (-0.001, 0.074, "rmse", "undetermined", "undetermined within ±0.075"),  # the 0.5 mm pad vs smooth
    (0.010, 0.030, "rmse", "equivalent", "equivalent within ±0.05"),
    (-0.080, 0.030, "rmse", "better", "better"),
    (0.080, 0.030, "rmse", "worse", "worse"),
    (0.080, 0.030, "ovl", "better", "better"),  # a higher overlap is better
    (0.000, 0.060, "ovl", "undetermined", "undetermined within ±0.060"),
])
def test_paired_verdicts(mean, half, metric, verdict, words):
    from roughsense.explore.paired import judge

    p = judge(_diffs(mean, half), metric)
    assert p.verdict == verdict and p.words() == words and p.n == 4
    assert (p.low, p.high) == (pytest.approx(mean - half), pytest.approx(mean + half))
    assert "smallest difference 4 seeds detect with 80 % power" in p.sentence()


def test_too_few_seeds_give_no_interval_and_bounded_levels_stay_in_range():
    from roughsense.explore.paired import judge, level

    two = judge([0.1, -0.2], "rmse")
    assert two.verdict == "too few seeds" and np.isnan(two.low) and np.isnan(two.mde)
    assert two.words() == "2 seeds: too few for an interval; run >= 3 seeds" and "[" not in two.sentence()
    assert np.isnan(level([0.7, 0.76], "ovl")[1])  # no more "0.730 ± 1.618"
    mean, low, high, n = level([0.1, 0.9, 0.98], "ovl")
    assert n == 3 and mean == pytest.approx(0.66) and (low, high) == (0.0, 1.0)
    _, low, high, _ = level([0.01, 0.5, 0.02], "rmse")
    assert low == 0.0 and high > 0.5
    wide = judge([0.9, -0.9, 0.95, -0.8], "ovl")  # a difference of two OVLs cannot leave [-1, 1]
    assert wide.low == -1.0 and wide.high == 1.0


def test_null_rmse_from_the_stored_targets_is_the_analysis_training_mean(two_model_cell):
    from roughsense.analysis.unseen import null_specimen_rmse
    from roughsense.explore.paired import null_rmse

    sweep, cell, study, features, summary, per_specimen = two_model_cell
    labels = [nominal_force_label(f) for f in study.forces_n]
    analysis = analyse_study(study, features=features, max_components=cell.max_components,
                             conditions=[*labels, "combined"], cv_schemes=cell.cv, combined_forces=labels,
                             n_permutations=0, models=("pls",))
    ours = null_rmse(per_specimen[per_specimen["model"] == "pls"])
    mine = per_specimen[per_specimen["model"] == "pls"]
    for fit in analysis.fits:
        rows = mine[(mine["condition"] == fit.condition) & (mine["cv"] == fit.cv)]
        g = rows["gmean"].to_numpy()
        k, reps = g.size, cell.repetitions  # per-specimen nulls, pooled over equal row counts: cv_rmse[0]
        pred = (g.sum() - g) / (k - 1) if fit.cv == "loso" else (reps * g.sum() - g) / (reps * k - 1)
        assert np.sqrt(np.mean((pred - g) ** 2)) == pytest.approx(fit.curve[0], rel=1e-9)
        assert ours.loc[(cell.id, fit.pad, fit.condition, fit.cv, "pls")] == pytest.approx(np.abs(pred - g).mean())
        if fit.cv == "loso":
            assert ours.loc[(cell.id, fit.pad, fit.condition, fit.cv, "pls")] == pytest.approx(
                null_specimen_rmse(fit.predictions, analysis.perceived).mean())


SEEDED = TINY.replace('pad = ["smooth"]', 'pad = ["smooth", "fingerprint"]').replace("[sweep]", '[sweep]\ncv = ["loso"]')


@pytest.fixture(scope="module")
def computed_cells() -> dict:
    """Cell id -> its rows, for the sweeps below that share cells (an id is the hash of everything a cell is, and
    a cell's rows are a function of it); read-only."""
    return {}


def _report_of(tmp_path: Path, seeds: str, computed: dict):
    """A tiny two-pad sweep's cells computed in this process (no Dask; each once per module) and its report."""
    from roughsense.explore.write_report import SUMMARY_CSV, write_explore_report

    sweep = read_sweep(_sweep_file(tmp_path, SEEDED.replace("seeds = [0, 1]", f"seeds = {seeds}")))
    store = ResultStore(tmp_path / "out", sweep)
    store.prepare()
    for cell in sweep.cells:
        if cell.id not in computed:
            computed[cell.id] = explore_cell.cell_rows(cell)
        store.write_cell(*computed[cell.id], cell.id)
    html = write_explore_report(sweep, tmp_path / "out").read_text()
    return sweep, pd.read_csv(tmp_path / "out" / SUMMARY_CSV), html


def test_two_seeds_report_no_interval_and_say_why(tmp_path, computed_cells):
    _, table, html = _report_of(tmp_path, "[0, 1]", computed_cells)
    assert "2 seeds: too few for an interval; run &gt;= 3 seeds" in html and "±" not in html
    assert table["rmse_ci95"].isna().all() and table["ci_low"].isna().all() and table["mde_80"].isna().all()
    assert set(table["verdict"]) <= {"the best design", "2 seeds: too few for an interval; run >= 3 seeds"}


def test_four_seeds_give_a_verdict_per_comparison(tmp_path, computed_cells):
    from scipy import stats

    _, table, html = _report_of(tmp_path, "[0, 1, 2, 3]", computed_cells)
    results = pd.read_parquet(tmp_path / "out" / "results")
    assert table.columns[-1] == "model" and {"diff_mean", "ci_low", "ci_high", "margin", "mde_80", "verdict",
                                              "n_paired", "null_rmse", "null_verdict"} <= set(table.columns)
    best = table[table["verdict"] == "the best design"]
    assert len(best) == 1
    for row in table[table["verdict"] != "the best design"].itertuples():
        own = results[(results["pad"] == row.pad) & (results["condition"] == row.condition)].set_index("seed")["rmse"]
        top = results[(results["pad"] == best["pad"].iloc[0]) & (results["condition"] == best["condition"].iloc[0])]
        d = own - top.set_index("seed")["rmse"]
        half = stats.t.ppf(0.975, 3) * d.std(ddof=1) / 2
        assert (row.diff_mean, row.ci_low, row.ci_high) == (pytest.approx(d.mean(), abs=1e-5),
                                                            pytest.approx(d.mean() - half, abs=1e-5),
                                                            pytest.approx(d.mean() + half, abs=1e-5))
        expected = ("worse" if d.mean() - half > 0 else "better" if d.mean() + half < 0 else
                    "equivalent within ±0.05" if d.mean() - half >= -0.05 and d.mean() + half <= 0.05 else
                    f"undetermined within ±{max(abs(d.mean() - half), abs(d.mean() + half)):.3f}")
        assert row.verdict == expected and row.n_paired == 4 and row.margin == 0.05 and row.mde_80 > 0
    assert (table["rmse_ci_low"] >= 0).all() and (table["ovl_ci_high"] <= 1).all()
    assert table["null_rmse"].notna().all() and table["null_verdict"].notna().all()
    assert "smallest difference 4 seeds detect with 80 % power" in html and "training mean" in html


def test_docs_quote_the_verdict_the_rule_gives_for_each_quoted_interval():
    """docs/explore.md's answers: every 'difference [low, high] | verdict' row is worded by the rule itself."""
    import re

    from roughsense.explore.paired import MARGINS

    text = (Path(__file__).parents[2] / "docs" / "explore.md").read_text()
    section = text[text.index("## The project's current answer"):]
    rows = re.findall(r"\| ([+-]\d\.\d{3}) \[([+-]\d\.\d{3}), ([+-]\d\.\d{3})\] \| ([^|]+) \| (\d\.\d{3}) \|", section)
    assert len(rows) == 8
    for mean, low, high, verdict, _mde in rows:
        mean, low, high = float(mean), float(low), float(high)
        assert low <= mean <= high
        if low > 0 or high < 0:
            assert verdict.strip() in ("better", "worse")
        elif -MARGINS["rmse"] <= low and high <= MARGINS["rmse"]:
            assert verdict.strip() == "equivalent within ±0.05"
        else:
            assert verdict.strip() == f"undetermined within ±{max(abs(low), abs(high)):.3f}"
    assert "undetermined within ±0.075" in section and "as good as" not in section.replace('"as good as"', "")


def test_a_sweep_with_every_cell_finished_starts_no_cluster(tmp_path, monkeypatch, run_cli):
    """Rerunning a finished sweep only rewrites its report: no Dask cluster (seconds to start) for nothing."""
    from roughsense.explore import runner

    path = _sweep_file(tmp_path, TINY.replace("seeds = [0, 1]", "seeds = [0]"))
    sweep = read_sweep(path)
    store = ResultStore(tmp_path / "out", sweep)
    store.prepare()
    for cell in sweep.cells:  # computed in this process, as a first run's workers would have
        store.write_cell(*explore_cell.cell_rows(cell), cell.id)

    def no_cluster(*args, **kwargs):
        raise AssertionError("a cluster was started for a sweep with nothing left to run")

    monkeypatch.setattr(runner, "connect", no_cluster)
    code, out, err = run_cli("explore", path, "--out", tmp_path / "out")
    assert (code, err) == (0, "") and "0 cells computed, 1 already finished" in out  # and no cluster (no_cluster)


# --------------------------------------------------------------------------- cells verified, not trusted (issue 22)


def _fake_rows(cell):
    """Rows shaped as cell_rows' (every column, one row per condition x CV x model), with made-up numbers: the store
    checks what a file is, not what a cell computes."""
    from roughsense.explore.sweep_cells import MODEL_KEY

    keys = [(c, v, m) for c in ("1N", "2N", "3N", "combined") for v in cell.cv for m in cell.models]
    summary = pd.DataFrame([{
        "cell": cell.id, "seed": cell.seed, "pad": cell.pad, "condition": c, "cv": v, "n_components": 2,
        "rmse": 0.3 + 0.01 * cell.seed, "ovl": 0.5, "ovl_predictive": 0.4, "cv_rmse": 0.3, "rmse_sd": 0.1,
        "ovl_sd": 0.1, "n_specimens": 4, MODEL_KEY: m} for c, v, m in keys])
    specimens = pd.DataFrame([{
        "cell": cell.id, "seed": cell.seed, "pad": cell.pad, "condition": c, "cv": v, "specimen": s,
        "shape": "rectangular", "wavelength_mm": 2.0, "n_components": 2, "gmean": 1.0 + 0.2 * i, "sd": 0.1,
        "pred_mean": 1.05 + 0.2 * i, "pred_sd": 0.1, "rmse": 0.3, "ovl": 0.5, "ovl_predictive": 0.4, MODEL_KEY: m}
        for c, v, m in keys for i, s in enumerate(["R2", "R4", "C3", "rect_1.5"])])
    design = cell.columns()
    design.pop("pad")
    design.pop(MODEL_KEY)
    return summary.assign(**design), specimens.assign(**design)


def _stored_sweep(tmp_path, seeds="[0, 1, 2, 3]"):
    sweep = read_sweep(_sweep_file(tmp_path, TINY.replace("seeds = [0, 1]", f"seeds = {seeds}")))
    store = ResultStore(tmp_path / "out", sweep)
    store.prepare()
    for cell in sweep.cells:
        store.write_cell(*_fake_rows(cell), cell.id)
    return sweep, store


def test_a_cell_file_is_checked_against_the_cell_its_name_says(tmp_path):
    import pyarrow.parquet as pq

    sweep, store = _stored_sweep(tmp_path, "[0, 1]")
    first, second = sweep.cells
    results = tmp_path / "out" / "results" / f"cell-{first.id}.parquet"
    specimens = tmp_path / "out" / "specimens" / f"cell-{first.id}.parquet"
    assert store.check_cell(first) is None and store.finished() == {first.id, second.id}
    intact = results.read_bytes()
    cases = [
        (results, intact[: len(intact) // 2], f"{results}: does not read back ("),  # killed mid-copy, full disk
        (specimens, b"", f"{specimens}: does not read back ("),
        (results, (tmp_path / "out" / "results" / f"cell-{second.id}.parquet").read_bytes(),
         f"{results}: is not the cell its name says (rows of cell '{second.id}')"),
    ]
    for path, content, problem in cases:
        saved = path.read_bytes()
        path.write_bytes(content)
        assert store.check_cell(first).startswith(problem)
        path.write_bytes(saved)
    frame = pd.read_parquet(results)
    for column, value, problem in (("seed", 9, "seed 9, not 0"), ("pad_modulus_mpa", 123.0, "pad_modulus_mpa 123, not"),
                                   ("model", "pls-x", "model families other than pls")):
        pq.write_table(_pa_table(frame.assign(**{column: value})), results)
        assert problem in store.check_cell(first)
    pq.write_table(_pa_table(frame.iloc[:0]), results)
    assert store.check_cell(first) == f"{results}: holds no rows"


def test_a_cell_file_missing_rows_its_design_promises_is_computed_again(tmp_path):
    """Issue 28.8: a cell whose rows of one condition (or model family) were dropped counted as finished."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from roughsense.explore.store import SPECIMEN_SCHEMA

    sweep, store = _stored_sweep(tmp_path, "[0]")
    (cell,) = sweep.cells
    results = tmp_path / "out" / "results" / f"cell-{cell.id}.parquet"
    specimens = tmp_path / "out" / "specimens" / f"cell-{cell.id}.parquet"
    frame, rows = pd.read_parquet(results), pd.read_parquet(specimens)
    pq.write_table(_pa_table(frame[frame.condition != "combined"]), results)
    assert store.check_cell(cell) == f"{results}: lacks the rows of combined loo pls (and 1 more)"
    pq.write_table(_pa_table(pd.concat([frame, frame.iloc[:1]])), results)
    assert store.check_cell(cell) == f"{results}: holds rows its cell's design does not promise, or one row twice"
    pq.write_table(_pa_table(frame), results)
    assert store.check_cell(cell) is None
    for kept, problem in ((rows[rows.cv != "loso"], "lacks the rows of 1N loso pls (and 3 more)"),
                          (rows.iloc[1:], "1N loo pls holds 3 specimen rows, its result row counts 4")):
        pq.write_table(pa.Table.from_pandas(kept[SPECIMEN_SCHEMA.names], schema=SPECIMEN_SCHEMA, preserve_index=False),
                       specimens)
        assert store.check_cell(cell) == f"{specimens}: {problem}"
    with pytest.warns(UserWarning, match="computing it again"):
        assert store.finished() == set()


def _pa_table(frame):
    import pyarrow as pa

    from roughsense.explore.store import RESULT_SCHEMA

    return pa.Table.from_pandas(frame[RESULT_SCHEMA.names], schema=RESULT_SCHEMA, preserve_index=False)


def test_damaged_cells_are_computed_again_and_said_never_a_crash(tmp_path, monkeypatch, run_cli):
    """Issue 22: a truncated results file, an empty specimens file and a file holding another cell's rows."""
    from distributed import Client, LocalCluster

    from roughsense.explore import runner

    sweep, _ = _stored_sweep(tmp_path)
    out = tmp_path / "out"
    a, b, c, d = (cell.id for cell in sweep.cells)
    results, specimens = out / "results", out / "specimens"
    (results / f"cell-{a}.parquet").write_bytes((results / f"cell-{a}.parquet").read_bytes()[:300])
    (specimens / f"cell-{b}.parquet").write_bytes(b"")
    (results / f"cell-{c}.parquet").write_bytes((results / f"cell-{d}.parquet").read_bytes())
    untouched = (results / f"cell-{d}.parquet").stat().st_mtime_ns
    computed = []

    def counted_rows(cell):
        computed.append(cell.id)
        return _fake_rows(cell)

    monkeypatch.setattr(explore_cell, "cell_rows", counted_rows)  # the in-process worker below runs this
    monkeypatch.setattr(runner, "connect", lambda *args, **kwargs: Client(
        LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"), set_as_default=False))
    code, stdout, err = run_cli("explore", _sweep_file(tmp_path, TINY.replace("seeds = [0, 1]", "seeds = [0, 1, 2, 3]")),
                                "--out", out)
    assert code == 0, err
    assert "3 cells computed, 1 already finished" in stdout and sorted(computed) == sorted([a, b, c])
    warned = [line for line in err.splitlines() if line.startswith("roughsense: warning: ")]
    assert len(warned) == 1 and "(and 2 more); computing these cells again" in warned[0], err
    assert any(f"{path}: " in warned[0] for path in (results / f"cell-{a}.parquet", specimens / f"cell-{b}.parquet",
                                                     results / f"cell-{c}.parquet"))
    stored = pd.read_parquet(results)
    assert sorted(stored.groupby("cell")["seed"].first().items()) == sorted((cell.id, cell.seed) for cell in sweep.cells)
    assert len(pd.read_parquet(specimens)) == 4 * len(_fake_rows(sweep.cells[0])[1])
    assert (results / f"cell-{d}.parquet").stat().st_mtime_ns == untouched  # a sound cell is not recomputed


def test_the_report_leaves_out_a_file_that_does_not_read_back(tmp_path):
    from roughsense.explore.write_report import write_explore_report

    sweep, _ = _stored_sweep(tmp_path, "[0, 1, 2]")
    damaged = tmp_path / "out" / "results" / f"cell-{sweep.cells[0].id}.parquet"
    damaged.write_bytes(damaged.read_bytes()[:100])
    with pytest.warns(UserWarning, match="does not read back") as caught:
        write_explore_report(sweep, tmp_path / "out")
    assert str(damaged) in str(caught[0].message)


def test_the_shipped_tiny_sweep_runs_enough_seeds_for_intervals():
    """tiny.toml is the first sweep a user runs: its report must conclude (intervals, verdicts), not say "too few"."""
    from roughsense.explore.paired import MIN_SEEDS

    shipped = Path(__file__).resolve().parents[2] / "src" / "roughsense" / "data" / "examples" / "tiny.toml"
    sweep = read_sweep(shipped)
    assert len({cell.seed for cell in sweep.cells}) >= MIN_SEEDS


@pytest.mark.parametrize(("verdict", "rmse", "words"), [
    ("below the training mean (2 seeds: too few for an interval; run >= 3 seeds)", 0.3,
     "design (combined) is below the training mean (2 seeds"),
    ("not below the training mean (2 seeds: too few for an interval; run >= 3 seeds)", 0.5,
     "design (combined) is not below the training mean"),
    ("does not beat the training mean", 0.3, "does not beat the training mean under LOSO: RMSE 0.300 against 0.400 "
     "(lower, but the paired 95 % interval of the difference includes 0)."),
])
def test_the_best_design_flag_is_a_sentence(monkeypatch, verdict, rmse, words):
    from roughsense.explore import write_report as report

    table = pd.DataFrame([{"model": "pls", "condition": "combined", "cv": "loso", "rmse": rmse, "null_rmse": 0.4,
                           "null_verdict": verdict}])
    monkeypatch.setattr(report, "best_per_model", lambda frame: [{"model": "pls", "condition": "combined"}])
    monkeypatch.setattr(report, "_match", lambda frame, anchor: pd.Series(True, index=frame.index))
    [flag] = report._best_flags(table)
    assert flag.startswith("The best pls design") and words in flag


@pytest.mark.parametrize("figure_format", ["svg", "pdf"])
def test_explore_writes_its_figures_in_the_format_asked(two_model_cell, tmp_path, figure_format):
    """Issue 30: --figure-format and --dpi on explore as on study: each axis's figure a file beside index.html,
    shown on the page (SVG as is; a PNG for a PDF) and linked."""
    from roughsense.explore.write_report import write_explore_report
    from roughsense.report.html import FigureStyle

    sweep, cell, *_, summary, per_specimen = two_model_cell
    store = ResultStore(tmp_path / "out", sweep)
    store.prepare()
    store.write_cell(summary, per_specimen, cell.id)
    index = write_explore_report(sweep, tmp_path / "out", style=FigureStyle(figure_format, 60))
    written = sorted((tmp_path / "out").glob(f"axis_*.{figure_format}"))
    assert written
    html = index.read_text()
    mime = "image/svg+xml" if figure_format == "svg" else "image/png"
    for path in written:
        assert f'href="{path.name}"' in html and f'data-name="{path.name}"' in html
        assert path.read_bytes()[:5] == (b"<?xml" if figure_format == "svg" else b"%PDF-")
    assert f"data:{mime};base64," in html
