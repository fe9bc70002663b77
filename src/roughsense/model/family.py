"""What a model family must offer for its whole life, so that no generic module names a family.

A family engine (:class:`FamilyEngine`) owns, for its family:

- the study: its cross-validation under the study's folds, its CV on shuffled targets (the permutation control),
  the applicability flags its held-out fits would have raised (its domain flags), and the extras only some families
  can afford (a nested interval check, stricter schemes, surfaces read from a few presses);
- ``fit``: the options it takes (declared in the registry, checked by :meth:`~FamilyEngine.check_options`), the CV
  ``fit`` runs and the fitted model (:meth:`~FamilyEngine.train`, a :class:`Trained`), the training record's fields
  it adds (and their schema), and the table and lines ``fit`` prints (:meth:`~FamilyEngine.fit_report`);
- its model-file section (``kind``): written (:meth:`~FamilyEngine.section`), checked (field code, JSON Schema and
  cross-field facts) and loaded as a fitted estimator (:meth:`~FamilyEngine.load`);
- the jackknife+ fold models a model file keeps: fitted (:meth:`~FamilyEngine.jackknife`), written (the folds'
  ``to_dict``) and checked and loaded (:meth:`~FamilyEngine.load_folds`).

Arrays in, arrays out: frames, judging and messages naming a pad or condition stay in the analysis layer. The
registry (:mod:`.registry`) lists the families in table order and imports each engine when first asked for.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Protocol

import numpy as np
import pandas as pd

#: The keywords a family's settings pass on to the peak law's kernels, in the order they always had.
SETTING_KEYS = ("freq_per_mm", "n_blocks", "pad_ridge_period_mm", "surfaces")
#: The keywords that carry each row's contact measures (never passed to the peak law's kernels).
CONTACT_KEYS = ("contact", "contact_names")


@dataclass(frozen=True, eq=False)
class FoldSettings:
    """What a pad x condition fixes for every family's folds: the frequency grid, how many spectra a row holds,
    the pad's ridge period (left out of a peak search) and each row's surface (its specimen: presses of one surface
    share where its peak is read). A PLS fit needs none of it; a peak readout needs all of it.

    ``contact`` (n, len(``contact_names``)) holds each row's contact measures read from its images
    (``sensor/contact_geometry.py``), force block by force block as the spectra are, each column named
    ``MEASURE@CONDITION`` (``groove_mm@1N``); a family that reads the contact (``reads_contact``) reads them here."""

    freq_per_mm: np.ndarray
    n_blocks: int = 1
    pad_ridge_period_mm: float | None = None
    surfaces: np.ndarray | None = None
    contact: np.ndarray | None = None
    contact_names: tuple[str, ...] = ()

    @classmethod
    def of(cls, settings: FoldSettings | Mapping | None) -> FoldSettings | None:
        """The settings from the keyword dict the analysis has always passed (``law_settings``), or as given."""
        if settings is None or isinstance(settings, FoldSettings):
            return settings
        return cls(**{key: settings[key] for key in (*SETTING_KEYS, *CONTACT_KEYS) if key in settings})

    @property
    def has_contact(self) -> bool:
        """Whether the rows carry contact measures (a study read before they existed carries none)."""
        return self.contact is not None and bool(self.contact_names)

    def keywords(self) -> dict:
        """Every setting as the keyword dict the analysis passes around (:meth:`of` reads it back): the peak law's,
        then the contact measures where the rows have them."""
        if self.contact is None:
            return self.law()
        return {**self.law(), "contact": self.contact, "contact_names": self.contact_names}

    def law(self) -> dict:
        """The peak law's keywords (peak_law_cv, held_out_flags, law_fold_models ...), in their usual order."""
        return {key: getattr(self, key) for key in SETTING_KEYS}


@dataclass(frozen=True)
class FoldResult:
    """One family cross-validated under one set of folds.

    ``curve``: index 0 the training mean's RMSE under the same folds, then the family's own (PLS: one per component
    count; a family that chooses nothing: one). ``best``/``one_se``: the index ``curve`` is read at (the chosen
    count, or 1). ``per_specimen``: a nested choice per held-out specimen (PLS under LOSO), else empty.
    """

    out_of_fold: np.ndarray
    curve: np.ndarray
    best: int = 1
    one_se: int = 1
    per_specimen: dict[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class TrainingSet:
    """What ``fit`` hands a family: every trial of one pad x condition (``specimens`` as the manifest names them),
    the CV ``scheme`` the user chose (``"loo"``, ``"loso"`` or K folds shuffled from ``seed``), its fold ids
    (``folds``, named ``fold_scheme``: the same for every family) and the training mean's out-of-fold predictions
    under them (``baseline``), the settings of a peak readout, the family's declared options by keyword (None: not
    given), and what a refusal names (``what``: the pad and condition; ``source``: the study's manifest)."""

    X: np.ndarray
    y: np.ndarray
    specimens: np.ndarray
    scheme: str | int
    seed: int
    folds: np.ndarray
    fold_scheme: str
    baseline: np.ndarray
    settings: FoldSettings
    options: Mapping[str, object]
    what: str
    source: Path | None = None


@dataclass(frozen=True)
class Trained:
    """A family's fit for a model file: the model fitted on every trial (its :meth:`FamilyEngine.section` writes it),
    the CV ``fit`` ran (``cv.scheme`` names its folds), the component count chosen (1 where nothing is chosen) and
    the fields it adds to the training record, in the order the file keeps them."""

    model: object
    cv: object
    n_components: int
    record: dict


def cv_rmse(prediction: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Root mean squared error over the last axis: one per target column of a batch of shufflings."""
    return np.sqrt(np.mean((prediction - target) ** 2, axis=-1))


class FamilyEngine(Protocol):
    """A registered family's whole life (:func:`roughsense.model.registry.engines`); NumPy in, NumPy out.

    The optional capabilities default to "none" here, so a family that subclasses this protocol states only
    what it has; the analysis skips a table's rows where a family returns None.
    """

    #: The registry's name of the family (:class:`roughsense.model.registry.Family`).
    name: ClassVar[str]
    #: Its model-file section's ``kind``: the one place the string is written.
    kind: ClassVar[str]
    #: Its section as JSON Schema (model/schema.py checks it after :meth:`load`, which gives the reasons first).
    section_schema: ClassVar[dict] = {}
    #: The fields it adds to the ``training`` record (JSON Schema properties), beside every family's.
    training_schema: ClassVar[dict] = {}
    #: The fields of its jackknife+ folds (JSON Schema properties, ``kind`` aside).
    fold_schema: ClassVar[dict] = {}
    #: Where its section keeps the pad's ridge period it leaves out of a peak search (a dotted place within the
    #: section), checked against the training record's; None: it reads no peak.
    ridge_period_place: ClassVar[str | None] = None
    #: Whether a surface's presses are read together (a press alone reads differently): the model file's interval
    #: then also covers a press read without its surface.
    reads_surfaces: ClassVar[bool] = False
    #: Whether it reads each row's contact measures (``FoldSettings.contact``) rather than, or beside, the spectra.
    #: Its loaded model, and its jackknife+ folds, then take them as a keyword beside X: ``predict(X, surfaces=None,
    #: contact=None)``, ``applicability(...)``, ``log_predict(...)`` (model/scoring.py's ``contact_inputs``).
    reads_contact: ClassVar[bool] = False

    def cross_validate(self, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, cv: str,
                       settings: FoldSettings | None, max_components: int) -> FoldResult:
        """Out-of-fold predictions under LOO (``cv="loo"``) or leave-one-specimen-out (``"loso"``)."""
        ...

    def largest_count(self, max_components: int) -> int:
        """The largest component count its CV chooses among, which the folds must support (1: it chooses none)."""
        return 1

    def permuted_rmse(self, X: np.ndarray, Y: np.ndarray, specimens: np.ndarray, cv: str,
                      settings: FoldSettings | None, max_components: int) -> np.ndarray:
        """The pooled CV RMSE of each shuffled target column of Y, the whole selection rerun on each."""
        ...

    def held_out_flags(self, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, settings: FoldSettings | None,
                       fold: FoldResult) -> np.ndarray | None:
        """Whether each trial lay outside the applicability domain of the model fitted without its specimen."""
        return None

    def interval_check(self, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, settings: FoldSettings | None,
                       seed: int) -> pd.DataFrame | None:
        """The fully nested jackknife+ check of each surface's interval, where leave-two-out fits are affordable."""
        return None

    def scheme_predictions(self, X: np.ndarray, targets: np.ndarray, specimens: np.ndarray, folds: np.ndarray,
                           settings: FoldSettings | None, max_components: int
                           ) -> tuple[np.ndarray, np.ndarray | None] | None:
        """Out-of-fold predictions (B, n) under any ``folds`` of the target columns (n, B) it can afford (at least
        the first, the real one), and the held-out flags under those folds; None where the folds are too small."""
        return None

    def surface_reader(self, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, settings: FoldSettings | None
                       ) -> Callable[[np.ndarray, np.ndarray], np.ndarray] | None:
        """``read(rows, surfaces)``: each row's prediction by the model fitted without its specimen, the rows of
        one label read as one surface (how many presses a surface needs); None when a press is read alone."""
        return None

    def jackknife(self, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, settings: FoldSettings | None,
                  fold: FoldResult, seed: int):
        """The leave-one-specimen-out fold models and residuals a model file keeps for the jackknife+, or None."""
        return None

    # ----------------------------------------------------------------------- fit

    def check_options(self, options: Mapping[str, object]) -> None:
        """Refuse a value of one of its declared options (by keyword, None: not given) before any image is read."""

    def train(self, data: TrainingSet) -> Trained:
        """The CV ``fit`` runs under ``data.scheme`` and the model fitted on every trial, with its record's fields;
        a refusal is one line naming ``data.what``."""
        ...

    def fit_report(self, trained) -> tuple[pd.DataFrame, list[str]]:
        """What ``fit`` prints of ``trained`` (``.model``, ``.cv``, ``.n_components``): its CV table, then lines."""
        ...

    # ----------------------------------------------------------------------- its model-file section

    def section(self, model) -> dict:
        """The model file's ``model`` section of a fitted model (``{"kind": kind, ...}``)."""
        ...

    def check_fields(self, section: dict, path: Path | None) -> int:
        """Its fields, shapes and bounds, each refusal one line naming ``path``; returns the feature count."""
        ...

    def load(self, section: dict, features: dict, *, training: dict, roughsense_version: str, path: Path | None):
        """The checked section as the fitted estimator (``family``, ``predict``, ``applicability``, ``model_file_``:
        :class:`roughsense.model.loaded.ModelFileInfo`)."""
        ...

    def check_written(self, section: dict, features: dict, training: dict) -> None:
        """Refuse, before a file is written, what loading it would refuse (by default: load it)."""
        self.check_fields(section, None)
        self.load(section, features, training=training, roughsense_version="", path=None)

    def check_section(self, section: dict, document: dict, fail: Callable[[str, str], None]) -> None:
        """Facts relating its section's fields that the schema cannot state (``fail(field, message)``)."""

    def check_training(self, training: dict, section: dict, fail: Callable[[str, str], None]) -> None:
        """Facts relating its training record's fields to its section (``fail(field, message)``)."""

    # ----------------------------------------------------------------------- its jackknife+ folds

    def load_folds(self, stored: dict, loaded, names: list, path: Path | None):
        """The file's fold models (``training.jackknife_plus.folds``) checked against ``loaded``, as the folds
        :meth:`jackknife` kept (``kind``, ``log_predict``, ``to_dict``, ``bracket``); None: it keeps none."""
        return None
