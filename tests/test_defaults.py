"""roughsense.defaults is each default's one home: the layers read it, none keeps a copy under another name."""
from __future__ import annotations

import ast
import inspect
from pathlib import Path

import numpy as np

from roughsense import defaults

SRC = Path(defaults.__file__).parent


def _copies(path: Path, root: Path = SRC) -> list[str]:
    """Module-level names bound to a default under another name: ``X = defaults.Y`` or ``from ..defaults import Y as X``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []
    for node in tree.body:
        if isinstance(node, ast.Assign) and isinstance(node.value, ast.Attribute) \
                and isinstance(node.value.value, ast.Name) and node.value.value.id == "defaults":
            found += [f"{path.relative_to(root)}:{node.lineno}: {t.id}" for t in node.targets if isinstance(t, ast.Name)]
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[-1] == "defaults":
            found += [f"{path.relative_to(root)}:{node.lineno}: {a.asname}" for a in node.names if a.asname]
    return found


def test_no_module_keeps_a_default_under_another_name():
    paths = [p for p in SRC.rglob("*.py") if p != SRC / "defaults.py"]
    assert len(paths) > 100
    assert [copy for path in paths for copy in _copies(path)] == []


def test_the_search_finds_a_copy(tmp_path):
    module = tmp_path / "copy.py"
    module.write_text("from .. import defaults\nfrom ..defaults import DPI as DOTS\nDEFAULT_DPI = defaults.DPI\n")
    assert _copies(module, tmp_path) == ["copy.py:2: DOTS", "copy.py:3: DEFAULT_DPI"]


def _default(function, name: str):
    return inspect.signature(function).parameters[name].default


def test_the_spectrum_reads_its_defaults_from_their_home():
    from roughsense.model.peak_law.law import PeakPowerLaw
    from roughsense.sensor.grid import frequency_grid, line_amplitude
    from roughsense.sensor.line import scale_misfit, spatial_spectrum
    from roughsense.sensor.spectrum import SpatialSpectrum

    home = (defaults.F_MIN_PER_MM, defaults.F_MAX_PER_MM, defaults.N_FREQS, defaults.ROWS, defaults.WINDOW)
    assert home == (0.1, 1.0, 45, 1, "hann")  # the paper's band and grid, one row, and the Hann taper (section 3.2)
    transformer = SpatialSpectrum()
    assert (transformer.f_min_per_mm, transformer.f_max_per_mm, transformer.n_freqs, transformer.rows,
            transformer.window) == home
    assert tuple(_default(spatial_spectrum, k) for k in ("f_min_per_mm", "f_max_per_mm", "n_freqs", "rows",
                                                          "window")) == home
    assert (_default(scale_misfit, "f_min_per_mm"), _default(scale_misfit, "f_max_per_mm")) == home[:2]
    assert _default(line_amplitude, "window") == defaults.WINDOW
    grid = frequency_grid()
    assert (grid[0], grid[-1], grid.size) == home[:3]
    assert np.array_equal(PeakPowerLaw()._grid(45), grid)  # the law given no grid reads the same band


def test_the_twin_reads_its_defaults_from_their_home():
    from roughsense.sim.config import SimulationConfig
    from roughsense.sim.optics import Camera
    from roughsense.sim.pads import make_pad

    config = SimulationConfig()
    assert (config.seed, config.fingerprint_period_mm, config.ridge_height_mm, config.ratings_from) == (
        defaults.SEED, defaults.FINGERPRINT_PERIOD_MM, defaults.RIDGE_HEIGHT_MM, defaults.RATINGS_FROM)
    assert (Camera().stored_height_px, Camera().px_per_mm) == (defaults.STORED_HEIGHT_PX, defaults.PX_PER_MM)
    assert _default(make_pad, "ridge_height_mm") == defaults.RIDGE_HEIGHT_MM


def test_a_sweep_reads_its_design_defaults_from_their_homes():
    from roughsense.explore.sweep import DEFAULTS
    from roughsense.paper import PAPER_FORCES_N, PAPER_REPETITIONS

    assert (DEFAULTS["fingerprint_period_mm"], DEFAULTS["ridge_height_mm"], DEFAULTS["ratings_from"]) == (
        defaults.FINGERPRINT_PERIOD_MM, defaults.RIDGE_HEIGHT_MM, defaults.RATINGS_FROM)
    assert (DEFAULTS["forces_n"], DEFAULTS["repetitions"]) == (PAPER_FORCES_N, PAPER_REPETITIONS)


def test_the_ridge_exclusion_and_the_component_and_shuffling_counts_have_one_home():
    """The peak search, the law and PLS's readout leave out the band the sensor leaves out; PLS's CV and the
    controls default to defaults' counts (each was once a second constant in model/ or analysis/)."""
    from roughsense.analysis.assessment import assess_unseen
    from roughsense.model.peak_law.law import PeakPowerLaw
    from roughsense.model.peak_search import peak_features
    from roughsense.model.pls.cv import pls_cv, pls_cv_many
    from roughsense.sensor.band import RIDGE_EXCLUSION_PER_MM

    assert _default(peak_features, "exclusion_per_mm") is RIDGE_EXCLUSION_PER_MM
    assert PeakPowerLaw().exclusion_per_mm is RIDGE_EXCLUSION_PER_MM
    assert _default(pls_cv, "max_components") == _default(pls_cv_many, "max_components") == defaults.MAX_COMPONENTS
    assert _default(assess_unseen, "n_permutations") == defaults.PERMUTATIONS
