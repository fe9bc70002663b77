"""A study's analysed results, computed once: every fit, control and summary the report and the command line render.

:func:`roughsense.analysis.study_analysis.analyse_study` builds them in stages, and each stage returns its own frozen
record: the study's facts (:class:`StudyFacts`), what is run (:class:`RunSettings`), the fits
(:class:`CrossValidation`), their controls (:class:`Controls`), the stricter held-out schemes
(:class:`StricterSchemes`), the paper's comparisons (:class:`PaperComparisons`) and the summary of surfaces never
seen (:class:`UnseenSurfaces`). A stage is handed only the records it needs, so their order shows in the types.
:class:`StudyResults` is all of them at once, assembled when the last stage is done: no field waits for a later
stage. The views (``results``, ``predictions``, ``cv_table`` ...) compute nothing new, they arrange what the fits
hold. Where the data came from (:class:`Provenance`) is decided here once, from the study folder, and every sentence
about it is worded in one place (roughsense.report.provenance)."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Literal

import numpy as np
import pandas as pd

from .. import paper
from ..model.registry import PAPER_MODEL, default_model
from . import dataset
from .evidence import evidence_words
from .family_fits import FamilyFit
from .geometry import specimen_geometries
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


@dataclass(frozen=True, eq=False)  # tables compare by identity: two records are equal only if they are one
class StudyFacts:
    """The study as the analysis reads it, before any model is fitted (the first stage).

    ``perceived`` (targets per specimen), ``shapes`` and ``wavelengths`` (per specimen), ``freq_per_mm`` and
    ``mean_spectra`` (per pad x specimen x condition), ``provenance``, whether the paper's per-specimen values
    describe it (``paper_pads``, ``paper_note``), which surfaces its evidence covers (``evidence``, words from
    its rated specimens: analysis/evidence.py) and each specimen's land/groove geometry (``geometries``,
    analysis/geometry.py; empty, with ``geometry_note`` saying why, where no geometry can be held out)."""

    study_name: str
    reference_specimen: str
    perceived: pd.DataFrame
    shapes: dict[str, str]
    wavelengths: dict[str, float]
    freq_per_mm: np.ndarray
    mean_spectra: pd.DataFrame
    provenance: Provenance
    paper_pads: tuple[str, ...]
    paper_note: str
    evidence: str
    geometries: dict[str, str]
    geometry_note: str

    @property
    def fit_default(self) -> str:
        """What ``roughsense fit`` writes by default on this study: by whether its rectangles vary land against
        groove (model/registry.py's ``default_model``)."""
        return default_model(bool(self.geometries))

    @classmethod
    def of(cls, study, perceived: pd.DataFrame, features: pd.DataFrame, conditions: tuple[str, ...]) -> StudyFacts:
        """The facts of a read study folder (roughsense.io.study.Study) with its targets (``perceived``) and spectra
        (``features``); the ``conditions`` analysed decide whether the paper's values describe it."""
        freq_columns = dataset.frequency_columns(features)
        mean_spectra = dataset.plain_names(
            features.groupby(["pad", "specimen", "condition"], sort=False)[freq_columns].mean().reset_index())
        paper_pads, paper_note = paper_comparability(
            study.specimen_names, study.pads, conditions, study.reference_specimen)
        specimens = study.specimens
        wavelengths = pd.to_numeric(specimens.get("wavelength_mm", pd.Series(np.nan, index=specimens.index)),
                                    errors="coerce")
        geometries, geometry_note = specimen_geometries(specimens)
        return cls(study_name=study.name, reference_specimen=study.reference_specimen, perceived=perceived,
                   shapes=dict(zip(specimens["specimen"], specimens["shape"])),
                   wavelengths=dict(zip(specimens["specimen"], wavelengths)),
                   freq_per_mm=dataset.column_frequencies(freq_columns), mean_spectra=mean_spectra,
                   provenance=Provenance.of(study), paper_pads=paper_pads, paper_note=paper_note,
                   evidence=evidence_words(specimens, perceived["specimen"]),
                   geometries=geometries, geometry_note=geometry_note)


def paper_comparability(specimens: Sequence[str], pads: Sequence[str], conditions: Sequence[str],
                        reference_specimen: str) -> tuple[tuple[str, ...], str]:
    """The pads whose results may stand beside the paper's, and one note on why the others may not.

    The paper's numbers describe its 14 specimens, its two pads, its three forces and their combination,
    with R3 as the reference; beside any other design they would read as a comparison that is not one.
    """
    paper_specimens = list(paper.PAPER_SPECIMENS)
    problems = []
    added = [str(s) for s in specimens if s not in paper_specimens]
    if set(specimens) > set(paper_specimens):  # e.g. the twin's paper+grooves: the paper's models saw only the 14
        problems.append(f"it adds {', '.join(added)} to the paper's {len(paper_specimens)} specimens, and every model "
                        "here is fitted on all of them")
    elif set(specimens) != set(paper_specimens):
        problems.append(f"its specimens ({', '.join(map(str, specimens))}) are not the paper's "
                        f"{len(paper_specimens)} ({', '.join(paper_specimens)})")
    if list(conditions) != list(paper.PAPER_CONDITIONS):
        problems.append(f"its conditions ({', '.join(conditions)}) are not the paper's {', '.join(paper.PAPER_CONDITIONS)}")
    if reference_specimen != paper.REFERENCE_SPECIMEN:
        problems.append(f"its reference is {reference_specimen}, the paper's {paper.REFERENCE_SPECIMEN}")
    if problems:
        return (), "The paper's values are not shown: " + "; ".join(problems) + "."
    matching = tuple(p for p in pads if p in paper.PAPER_PADS)
    others = [p for p in pads if p not in paper.PAPER_PADS]
    note = ""
    if others:
        note = (f"The paper's values are not shown for the {', '.join(others)} pad(s): the paper tested only the "
                f"{' and '.join(paper.PAPER_PADS)} pads.")
    return matching, note


@dataclass(frozen=True)
class RunSettings:
    """What the analysis runs besides the families: force ``conditions``, ``cv_schemes``, ``max_components`` and the
    permutation control's ``seed`` and ``n_permutations``."""

    conditions: tuple[str, ...]
    cv_schemes: tuple[str, ...]
    max_components: int
    seed: int
    n_permutations: int


@dataclass(frozen=True, eq=False)
class CrossValidation:
    """Every family cross-validated on every pad x condition x CV scheme (the second stage): ``models`` in the order
    of every table (the paper's first) and their ``fits``; the views arrange what the fits hold."""

    models: tuple[str, ...]
    fits: tuple[FamilyFit, ...]

    def condition_fit(self, pad: str, condition: str, cv: str = "loo", model: str = PAPER_MODEL) -> FamilyFit:
        """The cross-validated model of one pad, condition, CV scheme and family (a lookup: all fitted already)."""
        for item in self.fits:
            if (item.pad, item.condition, item.cv, item.model) == (pad, condition, cv, model):
                return item
        fitted = ", ".join(f"{f.model} {f.pad} {f.condition} {f.cv}" for f in self.fits) or "none"
        raise KeyError(f"no model for {model} {pad} {condition} {cv}; fitted: {fitted}")

    def ordered_fits(self) -> list[FamilyFit]:
        """The fits grouped by model family (the paper's rows first, as they were before any other family existed)."""
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
            frame["n_components"] = [item.per_specimen.get(str(s), item.best)
                                     for s in frame["specimen"]]
            frame["model"] = item.model
            frames.append(frame)
        return pd.concat(frames, ignore_index=True)

    def cv_table(self) -> pd.DataFrame:
        """The CV curves (n_components 0 is the training mean; a peak-law fit's 1 is the law)."""
        rows = []
        for item in self.ordered_fits():
            for n_components, rmse in enumerate(item.curve):
                rows.append({"pad": item.pad, "condition": item.condition, "cv": item.cv,
                             "n_components": n_components, "rmse": float(rmse), "model": item.model})
        return pd.DataFrame(rows, columns=["pad", "condition", "cv", "n_components", "rmse", "model"])

    def chosen_components(self) -> pd.DataFrame:
        return pd.DataFrame([
            {"pad": f.pad, "condition": f.condition, "cv": f.cv, "best_n_components": f.best,
             "one_se_n_components": f.one_se, "cv_rmse": float(f.curve[f.best]),
             "model": f.model}
            for f in self.ordered_fits()
        ])


@dataclass(frozen=True, eq=False)
class Controls:
    """Every fit against the training mean and specimen-shuffled targets: ``controls`` (controls.CONTROL_COLUMNS,
    then ``seed``, then ``model``)."""

    controls: pd.DataFrame


@dataclass(frozen=True, eq=False)
class StricterSchemes:
    """A period and a shape left out (``held_out``, HELD_OUT_COLUMNS) and presses per surface (``presses``,
    PRESS_COLUMNS; ``presses_needed``: (model, pad, condition) -> the presses a surface needs, None where no count
    beats the training mean), from the LOSO fits and their controls; empty where the run skipped them."""

    held_out: pd.DataFrame
    presses: pd.DataFrame
    presses_needed: dict

    @classmethod
    def skipped(cls) -> StricterSchemes:
        """What a run without the stricter schemes holds (a sweep cell's)."""
        return cls(pd.DataFrame(), pd.DataFrame(), {})


@dataclass(frozen=True, eq=False)
class PaperComparisons:
    """The paper's own tests on the paper's model (``tests``), its claims' verdicts (``claims``,
    claims.CLAIM_COLUMNS) and the predictive OVL of its published predictions (``paper_predictive``)."""

    tests: pd.DataFrame
    claims: pd.DataFrame
    paper_predictive: pd.DataFrame


@dataclass(frozen=True, eq=False)
class UnseenSurfaces:
    """How each model predicts a surface it never saw (``unseen``, UNSEEN_COLUMNS; empty without LOSO), the condition
    every such summary quotes (``headline_condition``), and the held-out specimens the default family (else the
    first fitted) is least sure of (``unsure``, UNSURE_COLUMNS)."""

    unseen: pd.DataFrame
    headline_condition: str
    unsure: pd.DataFrame


@dataclass(frozen=True, eq=False)
class StudyResults(UnseenSurfaces, PaperComparisons, StricterSchemes, Controls, CrossValidation, RunSettings,
                   StudyFacts):
    """One study analysed: every stage's record at once, each field computed once (see the stages' own docstrings).

    Built only by :meth:`assemble`, after the last stage. DataFrames stay mutable objects, but nothing assigns to a
    field after :func:`analyse_study` assembled the record.
    """

    @classmethod
    def assemble(cls, facts: StudyFacts, run: RunSettings, cross_validation: CrossValidation, controls: Controls,
                 stricter: StricterSchemes, paper: PaperComparisons, unseen: UnseenSurfaces) -> StudyResults:
        """The record of every stage, each field taken from the stage that computed it."""
        stages = (facts, run, cross_validation, controls, stricter, paper, unseen)
        return cls(**{f.name: getattr(stage, f.name) for stage in stages for f in fields(stage)})

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
