"""A study's analysed results: every fit's tables and the views the report and the command line render.

The record is filled by :func:`roughsense.analysis.study_analysis.analyse_study` only; its views (``results``,
``predictions``, ``cv_table`` ...) compute nothing new, they arrange what the fits hold."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..model.families import PLS
from ..model.pls_cv import DEFAULT_MAX_COMPONENTS
from .family_fits import ConditionFit
from .metrics import shape_summary
from .unseen import unseen_summary

CV_SCHEMES = ("loo", "loso")


#: The paper's schema first (paper_results.csv), then our additions; columns are only ever added.
RESULT_COLUMNS = ["pad", "specimen", "condition", "pred_mean", "pred_sd", "ovl", "rmse", "predictive_sd",
                  "ovl_predictive", "model"]


@dataclass
class StudyAnalysis:
    study_name: str
    reference_specimen: str
    perceived: pd.DataFrame
    shapes: dict[str, str]
    freq_per_mm: np.ndarray
    mean_spectra: pd.DataFrame
    fits: list[ConditionFit] = field(default_factory=list)
    tests: pd.DataFrame = field(default_factory=pd.DataFrame)
    max_components: int = DEFAULT_MAX_COMPONENTS
    #: One row per pad x condition x CV scheme (controls.CONTROL_COLUMNS): permutation test and null model.
    controls: pd.DataFrame = field(default_factory=pd.DataFrame)
    #: The paper's claims, each with our statistic, p and verdict (claims.CLAIM_COLUMNS).
    claims: pd.DataFrame = field(default_factory=pd.DataFrame)
    #: The paper's published predictions with the predictive OVL of a spread model (spread.paper_predictive).
    paper_predictive: pd.DataFrame = field(default_factory=pd.DataFrame)
    #: The study's [simulation] table (seed and settings) when a simulator wrote it; None for real data.
    simulation: dict | None = None
    #: study.toml's ``[study] synthetic``: where a folder's synthetic images came from (not measurements); None else.
    synthetic: str | None = None
    #: Whether the paper's per-specimen values describe this study, per pad, and why not where they do not.
    paper_pads: tuple[str, ...] = ()
    paper_note: str = ""
    seed: int = 0
    wavelengths: dict[str, float] = field(default_factory=dict)
    #: The model families fitted, in the order of every table (the paper's PLS first).
    models: tuple[str, ...] = (PLS,)
    #: Every LOSO fit again with a period, and a shape, held out (analysis/held_out.py; HELD_OUT_COLUMNS).
    held_out: pd.DataFrame = field(default_factory=pd.DataFrame)
    #: A held-out surface's error against the presses it is read from (analysis/presses.py; PRESS_COLUMNS).
    presses: pd.DataFrame = field(default_factory=pd.DataFrame)

    def condition_fit(self, pad: str, condition: str, cv: str = "loo", model: str = PLS) -> ConditionFit:
        """The cross-validated model of one pad, condition, CV scheme and family (a lookup: all fitted already)."""
        for item in self.fits:
            if (item.pad, item.condition, item.cv, item.model) == (pad, condition, cv, model):
                return item
        fitted = ", ".join(f"{f.model} {f.pad} {f.condition} {f.cv}" for f in self.fits) or "none"
        raise KeyError(f"no model for {model} {pad} {condition} {cv}; fitted: {fitted}")

    def ordered_fits(self) -> list[ConditionFit]:
        """The fits grouped by model family (PLS's rows first, as they were before any other family existed)."""
        return [f for model in self.models for f in self.fits if f.model == model]

    @property
    def pads(self) -> list[str]:
        return list(dict.fromkeys(f.pad for f in self.fits))

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

    def unseen_summary(self) -> pd.DataFrame:
        """How well each model predicts a surface it never saw: nested LOSO per model x pad x condition (unseen.py)."""
        return unseen_summary(self)

    @property
    def simulated(self) -> bool:
        return self.simulation is not None

    def summary(self, cv: str, column: str, model: str = PLS, results: pd.DataFrame | None = None) -> pd.DataFrame:
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
