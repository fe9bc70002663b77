"""One cell in memory: twin frames -> spectra -> the study's own analysis (LOO and nested LOSO) -> result rows.

Nothing is written. Frames are rendered only down to the row the sensor reads (the band above it too for a family that
reads the contact measures; bit-identical to those rows of the
whole frame) and each trial's contact levels start from the last solution of the same surfaces; the spectra come from
the sensor's own code on a frame of the camera's full size, and the analysis is :func:`analysis.study_analysis.analyse_study`
on an in-memory study, so a cell's numbers are the ones ``simulate`` + ``study`` give for the same design (to the
contact solver's tolerance; tests/explore/test_explore.py checks it). Every model family the cell asks for is fitted on the
same spectra (one simulation), and each result row names its family in the ``model`` column.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from .. import defaults
from ..analysis.dataset import contact_columns, spectrum_columns
from ..analysis.study_analysis import analyse_study
from ..errors import RoughsenseError
from ..io.protocol import assign_nominal_forces, nominal_force_label
from ..io.sensor_settings import SensorSettings
from ..io.study import Study
from ..model.registry import engine
from ..paper import REFERENCE_SPECIMEN
from ..sensor.line import resolve_roi
from ..sensor.spectrum import SpatialSpectrum
from ..sim.config import SimulationConfig, ridge_periods
from ..sim.frames import render_trial
from ..sim.manifest import trial_manifest
from ..sim.optics import Camera
from ..sim.plan import plan_trials
from .allocator import relax_frozen_malloc_thresholds
from .cell_panel import panel_ratings
from .sweep_cells import MODEL_KEY, Cell

RESULT_COLUMNS = ["cell", "seed", "pad", "condition", "cv", "n_components", "rmse", "ovl", "ovl_predictive", "cv_rmse",
                  "rmse_sd", "ovl_sd", "n_specimens"]
SPECIMEN_COLUMNS = ["cell", "seed", "pad", "condition", "cv", "specimen", "shape", "wavelength_mm", "n_components",
                    "gmean", "sd", "pred_mean", "pred_sd", "rmse", "ovl", "ovl_predictive"]


def sensor_roi(width_px: int, height_px: int):
    """The paper's centre crop where the frame holds it, else the largest centred crop of that shape that fits."""
    crop_w, crop_h = defaults.CENTER_CROP_PX
    if width_px >= crop_w and height_px >= crop_h:
        return "center"
    w, h = min(crop_w, width_px), min(crop_h, height_px)
    return ((width_px - w) // 2, (height_px - h) // 2, w, h)


def line_rows(spectrum: SpatialSpectrum, width_px: int, height_px: int, *, band: bool = False) -> tuple[int, int]:
    """The rows of a frame the sensor reads: the crop's central ``rows`` rows (as ``sensor.spectrum`` reads them);
    with ``band``, every row from the crop's top down to them (where the contact measures are read)."""
    x, y, w, h = resolve_roi(spectrum.roi, np.empty((height_px, width_px, 0), dtype=np.uint8))
    top = y + (h - spectrum.rows) // 2
    return (y if band else top), top + spectrum.rows


def simulation_config(cell: Cell) -> SimulationConfig:
    return SimulationConfig(
        pads=(cell.pad,), specimens=cell.specimens, forces_n=cell.forces_n, repetitions=cell.repetitions,
        seed=cell.seed, participants=cell.participants, sessions=cell.sessions,
        fingerprint_period_mm=cell.fingerprint_period_mm or SimulationConfig.fingerprint_period_mm,
        ridge_height_mm=cell.ridge_height_mm or SimulationConfig.ridge_height_mm,
        camera=Camera(width_px=cell.width_px, height_px=cell.height_px), ratings_from=cell.ratings_from,
    )


def cell_features(cell: Cell, *, warm_start: bool = True) -> tuple[Study, pd.DataFrame]:
    """The cell's study in memory (no images) and its feature table (manifest columns + spectrum)."""
    config = simulation_config(cell)
    pads, _ = config.validate()
    pads = [replace(p, young_pa=cell.pad_modulus_mpa * 1e6) for p in pads]
    contact = any(engine(model).reads_contact for model in cell.models)
    return design_features(config, pads=pads, warm_start=warm_start, label=f"explore cell {cell.id}", contact=contact)


def design_features(config: SimulationConfig, *, pads=None, warm_start: bool = True,
                    label: str = "simulated design", contact: bool = False) -> tuple[Study, pd.DataFrame]:
    """A simulated design's study in memory (no images) and its feature table (manifest columns + spectrum, and with
    ``contact`` each press's contact measures): what ``simulate`` + ``read_study`` + the sensor give for the same
    config, without writing or decoding a frame.

    Its manifest is the table a simulated folder's manifest.csv holds (sim.manifest), as the study reader returns it
    (images by name). ``pads`` replaces the config's pads (a sweep's modulus axis). The contact measures need the
    band above the line, so only a design that asks for them renders it (each pad's read with its own ridges).

    ``warm_start=False`` solves every contact from scratch, as ``simulate`` does: the features are then
    bit-identical to those of the simulated study folder (tests compare them).
    """
    valid_pads, specimens = config.validate()
    pads = valid_pads if pads is None else pads
    trials = plan_trials(config, pads, specimens)
    camera = config.camera
    height_px = getattr(camera, "frame_height_px", camera.height_px)  # the rows a frame holds (a sensor window)
    roi = sensor_roi(camera.width_px, height_px)
    spectrum = SpatialSpectrum(px_per_mm=camera.px_per_mm, roi=roi).fit()
    rows = line_rows(spectrum, camera.width_px, height_px, band=contact)
    warm: dict | None = {} if warm_start else None
    fractions = []

    def frames(chosen):
        frame = np.zeros((height_px, camera.width_px), dtype=np.uint8)  # rows the sensor never reads stay 0
        for trial in chosen:
            part, fraction = render_trial(trial, rows=rows, warm=warm)
            fractions.append(fraction)
            frame[rows[0]:rows[1]] = part
            yield frame

    if contact:
        X, measures, order = _contact_features(spectrum, trials, frames, ridge_periods(pads))
        fractions = [fractions[i] for i in np.argsort(order)]
    else:
        X = np.vstack(list(spectrum.iter_transform(frames(trials))))
    # The folder's manifest table (images by name: there are no files), with the conditions read_study gives it.
    manifest = assign_nominal_forces(trial_manifest(trials, [t.image for t in trials], fractions), config.forces_n)
    features = pd.concat([manifest, pd.DataFrame(X, columns=spectrum_columns(spectrum.freq_per_mm_))], axis=1)
    if contact:
        features = pd.concat([features, pd.DataFrame(measures, columns=contact_columns())], axis=1)
    study = Study(
        root=Path(label.replace(" ", "-")), name=label, reference_specimen=REFERENCE_SPECIMEN,
        sensor=SensorSettings(px_per_mm=camera.px_per_mm, roi=roi), forces_n=tuple(sorted(config.forces_n)),
        specimens=pd.DataFrame([s.table_row() for s in specimens]), manifest=manifest,
        ratings=panel_ratings(specimens, config.seed, ratings_from=config.ratings_from,
                              participants=config.participants, sessions=config.sessions),
        pad_ridge_period_mm=ridge_periods(pads),
    )
    return study, features


def _contact_features(spectrum: SpatialSpectrum, trials: list, frames, ridges: dict):
    """(spectra, contact measures, the order the trials were rendered in) of every trial, each pad's trials read with
    that pad's ridge period (a smooth pad's with none), in the trials' order."""
    X = np.empty((len(trials), spectrum.freq_per_mm_.size))
    measures = np.empty((len(trials), len(contact_columns())))
    order = []
    for pad in dict.fromkeys(t.pad.name for t in trials):
        chosen = [i for i, t in enumerate(trials) if t.pad.name == pad]
        pairs = spectrum.iter_transform_contact(frames([trials[i] for i in chosen]), ridge_period_mm=ridges.get(pad))
        for i, (row, measured) in zip(chosen, pairs):
            X[i], measures[i] = row, measured
        order.extend(chosen)
    return X, measures, np.array(order)


def cell_conditions(cell: Cell) -> tuple[list[str], list[str]]:
    """(force labels in order, conditions analysed): "combined" joins them when the design has several forces."""
    labels = [nominal_force_label(f) for f in sorted(cell.forces_n)]
    return labels, [*labels, "combined"] if len(labels) > 1 else labels


def result_keys(cell: Cell) -> set[tuple[str, str, str]]:
    """(condition, CV scheme, model family) of every result row the cell computes: what a finished cell holds."""
    return {(condition, cv, model) for condition in cell_conditions(cell)[1] for cv in cell.cv for model in cell.models}


def analyse_cell(cell: Cell):
    """The study analysis of one cell (every condition, CV scheme and model family)."""
    study, features = cell_features(cell)
    labels, conditions = cell_conditions(cell)
    # No permutation controls: a sweep compares designs by their error; the controls are the study report's job.
    return analyse_study(study, features=features, max_components=cell.max_components, conditions=conditions,
                         cv_schemes=cell.cv, combined_forces=labels, n_permutations=0, models=cell.models,
                         stricter=False), study


def cell_rows(cell: Cell) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(summary rows: one per pad x condition x CV scheme x model, per-specimen rows) of one cell."""
    analysis, study = analyse_cell(cell)
    shapes = dict(zip(study.specimens["specimen"], study.specimens["shape"]))
    wavelengths = dict(zip(study.specimens["specimen"], study.specimens["wavelength_mm"]))
    summary, per_specimen = [], []
    for fit in analysis.fits:
        table = fit.table
        rated = table[table["specimen"] != study.reference_specimen]
        summary.append({
            "cell": cell.id, "seed": cell.seed, "pad": fit.pad, "condition": fit.condition, "cv": fit.cv,
            "n_components": int(fit.best),
            "rmse": float(table["rmse"].mean()), "ovl": float(rated["ovl"].mean()),
            "cv_rmse": float(fit.curve[fit.best]),
            "rmse_sd": float(table["rmse"].std(ddof=1)) if len(table) > 1 else math.nan,
            "ovl_sd": float(rated["ovl"].std(ddof=1)) if len(rated) > 1 else math.nan,
            "n_specimens": int(len(table)),
            "ovl_predictive": float(rated["ovl_predictive"].mean()),
            MODEL_KEY: fit.model,
        })
        for row in table.itertuples(index=False):
            per_specimen.append({
                "cell": cell.id, "seed": cell.seed, "pad": fit.pad, "condition": fit.condition, "cv": fit.cv,
                "specimen": row.specimen, "shape": shapes.get(row.specimen, "other"),
                "wavelength_mm": float(wavelengths.get(row.specimen, math.nan)),
                "n_components": int(fit.per_specimen.get(str(row.specimen), fit.best)),
                "gmean": row.gmean, "sd": row.sd, "pred_mean": row.pred_mean, "pred_sd": row.pred_sd,
                "rmse": row.rmse, "ovl": row.ovl,
                "ovl_predictive": float(row.ovl_predictive),
                MODEL_KEY: fit.model,
            })
    design = cell.columns()
    design.pop("pad")  # the pad and model columns come from the analysis (one value each per row)
    design.pop(MODEL_KEY)
    summary_frame = pd.DataFrame(summary, columns=[*RESULT_COLUMNS, MODEL_KEY]).assign(**design)
    specimen_frame = pd.DataFrame(per_specimen, columns=[*SPECIMEN_COLUMNS, MODEL_KEY]).assign(**design)
    return summary_frame, specimen_frame


def error_line(exc: BaseException) -> str:
    """A failed cell's error as one line: a roughsense error's own words, anything else with its type."""
    text = str(exc) if isinstance(exc, RoughsenseError) else f"{type(exc).__name__}: {exc}"
    return " ".join(text.split()) or type(exc).__name__


def run_cell(cell: Cell) -> dict:
    """A Dask task: the cell's rows, or its one-line error (a failing cell never stops the sweep)."""
    started = time.perf_counter()
    relax_frozen_malloc_thresholds()  # Dask's workers start with a setting that slows a cell 2.4x
    try:
        from .code_fingerprint import code_fingerprint

        if cell.code and cell.code != code_fingerprint():
            raise RoughsenseError(f"this worker runs different roughsense code ({code_fingerprint()}) from the client "
                                  f"({cell.code}); install the same version on every worker")
        summary, per_specimen = cell_rows(cell)
        return {"cell": cell, "results": summary, "specimens": per_specimen, "error": None,
                "seconds": time.perf_counter() - started}
    except Exception as exc:
        return {"cell": cell, "results": None, "specimens": None, "error": error_line(exc),
                "seconds": time.perf_counter() - started}
