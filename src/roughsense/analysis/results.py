"""A study's analysed results, computed once: every fit, control and summary the report and the command line render.

:func:`roughsense.analysis.study_analysis.analyse_study` is the only builder. The record is frozen, so a renderer
cannot change what another renderer reads; its views (``results``, ``predictions``, ``cv_table`` ...) compute nothing
new, they arrange what the fits hold. Where the data came from (:class:`Provenance`) is decided here once, from the
study folder, and every sentence about it is worded in one place (roughsense.report.provenance)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pandas as pd

from .. import defaults
from ..model.registry import PAPER_MODEL
from .family_fits import ConditionFit
from .metrics import shape_summary

CV_SCHEMES = ("loo", "loso")


#: The paper's schema first (paper_results.csv), then our additions; columns are only ever added.
RESULT_COLUMNS = ["pad", "specimen", "condition", "pred_mean", "pred_sd", "ovl", "rmse", "predictive_sd",
                  "ovl_predictive", "model"]


@dataclass(frozen=True)
class Provenance:
    """Where a study's images and ratings came from, which decides what its numbers can claim.

    ``kind``: "simulated" (study.toml has a [simulation] table: the digital twin wrote it), "synthetic" (``[study]
    synthetic`` says the images are made, not measured, e.g. an example) or "user" (neither: findings about real
    data). ``seed`` and ``ratings_from`` are the simulation's (None where not recorded or not simulated); ``note`` is
    the synthetic folder's own account; ``settings`` the whole [simulation] table, shown in the report as written.
    """

    kind: Literal["simulated", "synthetic", "user"] = "user"
    seed: object = None
    ratings_from: str | None = None
    note: str | None = None
    settings: dict | None = None

    @classmethod
    def of(cls, study) -> Provenance:
        """The provenance of a read study folder (roughsense.io.study.Study)."""
        simulation, synthetic = study.simulation, study.synthetic
        if simulation is not None:
            return cls("simulated", simulation.get("seed"), simulation.get("ratings_from", "paper"), synthetic,
                       dict(simulation))
        return cls("synthetic" if synthetic else "user", note=synthetic or None)


def _empty() -> pd.DataFrame:
    return pd.DataFrame()


@dataclass(frozen=True, eq=False)  # tables compare by identity: two analyses are equal only if they are one
class StudyResults:
    """One study analysed: its facts, what was run, and everything computed from it, each once.

    The study: ``perceived`` (targets per specimen), ``shapes``, ``wavelengths``, ``freq_per_mm`` and ``mean_spectra``
    (per pad x specimen x condition), ``provenance``, and whether the paper's per-specimen values describe it
    (``paper_pads``, ``paper_note``). What was run: ``models`` (in the order of every table, the paper's first),
    ``conditions``, ``cv_schemes``, ``max_components``, ``seed`` and ``n_permutations``. Computed once: ``fits``, and
    the tables ``controls`` (controls.CONTROL_COLUMNS), ``tests``, ``claims`` (claims.CLAIM_COLUMNS),
    ``paper_predictive``, ``held_out`` (HELD_OUT_COLUMNS), ``presses`` (PRESS_COLUMNS) and ``unseen`` (UNSEEN_COLUMNS;
    empty without LOSO), ``headline_condition``, the condition every "surface left out" summary quotes, and ``unsure``
    (UNSURE_COLUMNS), the held-out specimens fit's default family (else the first fitted) is least sure of.
    DataFrames stay mutable objects, but nothing assigns to a field after :func:`analyse_study` built the record.
    """

    study_name: str
    reference_specimen: str
    perceived: pd.DataFrame
    shapes: dict[str, str]
    freq_per_mm: np.ndarray
    mean_spectra: pd.DataFrame
    wavelengths: dict[str, float] = field(default_factory=dict)
    provenance: Provenance = Provenance()
    paper_pads: tuple[str, ...] = ()
    paper_note: str = ""
    models: tuple[str, ...] = (PAPER_MODEL,)
    conditions: tuple[str, ...] = ()
    cv_schemes: tuple[str, ...] = CV_SCHEMES
    max_components: int = defaults.MAX_COMPONENTS
    seed: int = defaults.SEED
    n_permutations: int = defaults.PERMUTATIONS
    fits: tuple[ConditionFit, ...] = ()
    controls: pd.DataFrame = field(default_factory=_empty)
    tests: pd.DataFrame = field(default_factory=_empty)
    claims: pd.DataFrame = field(default_factory=_empty)
    paper_predictive: pd.DataFrame = field(default_factory=_empty)
    held_out: pd.DataFrame = field(default_factory=_empty)
    presses: pd.DataFrame = field(default_factory=_empty)
    unseen: pd.DataFrame = field(default_factory=_empty)
    headline_condition: str = ""
    unsure: pd.DataFrame = field(default_factory=_empty)
    #: (model, pad, condition) -> the presses a surface needs (analysis/presses.py; None: no count beats the mean).
    presses_needed: dict = field(default_factory=dict)

    def condition_fit(self, pad: str, condition: str, cv: str = "loo", model: str = PAPER_MODEL) -> ConditionFit:
        """The cross-validated model of one pad, condition, CV scheme and family (a lookup: all fitted already)."""
        for item in self.fits:
            if (item.pad, item.condition, item.cv, item.model) == (pad, condition, cv, model):
                return item
        fitted = ", ".join(f"{f.model} {f.pad} {f.condition} {f.cv}" for f in self.fits) or "none"
        raise KeyError(f"no model for {model} {pad} {condition} {cv}; fitted: {fitted}")

    def ordered_fits(self) -> list[ConditionFit]:
        """The fits grouped by model family (the paper's rows first, as they were before any other family existed)."""
        return [f for model in self.models for f in self.fits if f.model == model]

    @property
    def pads(self) -> list[str]:
        return list(dict.fromkeys(f.pad for f in self.fits))

    def unseen_summary(self) -> pd.DataFrame:
        """How well each model predicts a surface it never saw (analysis/unseen.py): the table analyse_study made."""
        return self.unseen

    # The study folder's tables as the analysis used to hold them, for code that still reads them; re-exported for
    # one release: read ``provenance`` instead.
    @property
    def simulation(self) -> dict | None:
        return self.provenance.settings

    @property
    def synthetic(self) -> str | None:
        return self.provenance.note

    @property
    def simulated(self) -> bool:
        return self.provenance.kind == "simulated"

    def results(self, cv: str = "loo") -> pd.DataFrame:
        """Per-specimen results in the schema of the paper's tables (paper_results.csv)."""
        frames = []
        for item in self.ordered_fits():
            if item.cv != cv:
                continue
            table = item.table.copy()
            table.insert(0, "pad", item.pad)
            table.insert(2, "condition", item.condition)
            table["model"] = item.model
            frames.append(table[RESULT_COLUMNS])
        return pd.concat(frames, ignore_index=True)

    def predictions(self) -> pd.DataFrame:
        """Every out-of-fold prediction: one row per trial (image, or the three images of a combined trial)."""
        frames = []
        for item in self.ordered_fits():
            frame = item.predictions.copy()
            frame.insert(0, "pad", item.pad)
            frame.insert(1, "condition", item.condition)
            frame.insert(2, "cv", item.cv)
            frame["n_components"] = [item.nested_n_components.get(str(s), item.best_n_components)
                                     for s in frame["specimen"]]
            frame["model"] = item.model
            frames.append(frame)
        return pd.concat(frames, ignore_index=True)

    def cv_table(self) -> pd.DataFrame:
        """The CV curves (n_components 0 is the training mean; a peak-law fit's 1 is the law)."""
        rows = []
        for item in self.ordered_fits():
            for n_components, rmse in enumerate(item.cv_rmse):
                rows.append({"pad": item.pad, "condition": item.condition, "cv": item.cv,
                             "n_components": n_components, "rmse": float(rmse), "model": item.model})
        return pd.DataFrame(rows, columns=["pad", "condition", "cv", "n_components", "rmse", "model"])

    def chosen_components(self) -> pd.DataFrame:
        return pd.DataFrame([
            {"pad": f.pad, "condition": f.condition, "cv": f.cv, "best_n_components": f.best_n_components,
             "one_se_n_components": f.one_se_n_components, "cv_rmse": float(f.cv_rmse[f.best_n_components]),
             "model": f.model}
            for f in self.ordered_fits()
        ])

    def summary(self, cv: str, column: str, model: str = PAPER_MODEL, results: pd.DataFrame | None = None) -> pd.DataFrame:
        """Mean ± SD of ``column`` over rectangular, circular and all specimens, per pad x condition, of one model.

        ``results``: ``self.results(cv)`` if the caller holds it already (a report summarises it a dozen times)."""
        results = self.results(cv) if results is None else results
        results = results[results["model"] == model]
        frames = []
        for (pad, condition), table in results.groupby(["pad", "condition"], sort=False):
            summary = shape_summary(table, self.shapes, column)
            summary.insert(0, "pad", pad)
            summary.insert(1, "condition", condition)
            frames.append(summary)
        return pd.concat(frames, ignore_index=True)


#: The record's name before it was frozen; re-exported for one release.
StudyAnalysis = StudyResults
