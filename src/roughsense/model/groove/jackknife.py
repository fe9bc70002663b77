"""The groove model's jackknife+ folds (model/jackknife_file.py): the model chosen and fitted without each specimen
(its own nested choice of terms), kept in a model file as intercept, one slope per offered term (0: not chosen),
and each term's training mean and range, read with the deployed model's contact columns.

Fitted in one batch (model/groove/cv.py), exactly as the study's leave-one-specimen-out fits them, so the file's
interval is the jackknife+ of the very folds whose errors the study reports. A press is read alone (each row its own
surface); the contact measures come with the rows (``contact``), as they do to the model's ``predict``.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import ModelFileError
from ..jackknife_file import KEY, deploy, fold_numbers
from .cv import fold_centres, fold_ranges, nested_fit, offered
from .file import KIND, _check_finite_predictions
from .terms import contact_terms

#: The folds' fields in a model file (``kind`` aside), as JSON Schema properties: those the peak law's folds also
#: name are declared as the peak law declares them (the families' fold fields share one schema).
FOLD_SCHEMA = {name: {"type": "array", "minItems": 1}
               for name in ("intercept", "coefficients", "term_mean", "term_min", "term_max")}


@dataclass(frozen=True)
class GrooveFolds:
    """The model fitted without each specimen: intercept (S,), slopes, term means and ranges (S, T) over the offered
    terms of ``contact_names``."""

    intercept: np.ndarray
    coefficients: np.ndarray
    term_mean: np.ndarray
    term_min: np.ndarray
    term_max: np.ndarray
    contact_names: tuple[str, ...]

    kind = KIND

    def log_predict(self, X, surfaces=None, contact=None) -> np.ndarray:
        """(S, n) each fold's log prediction of each row (``contact`` and ``surfaces`` as the model reads them)."""
        if contact is None:
            from .law import GrooveInputError

            raise GrooveInputError("the groove model's intervals read contact measures; none were given")
        terms, _ = contact_terms(contact, self.contact_names, surfaces)
        filled = np.where(np.isfinite(terms)[None], terms[None], self.term_mean[:, None, :])
        held = np.clip(filled, self.term_min[:, None, :], self.term_max[:, None, :])
        return self.intercept[:, None] + np.einsum("snt,st->sn", held, self.coefficients)

    def to_dict(self) -> dict:
        return {"kind": self.kind, "intercept": self.intercept.tolist(), "coefficients": self.coefficients.tolist(),
                "term_mean": self.term_mean.tolist(), "term_min": self.term_min.tolist(),
                "term_max": self.term_max.tolist()}

    def bracket(self, loaded) -> tuple[np.ndarray, np.ndarray, str]:
        """The folds' and the model's log roughness at the centre and corners of the model's trained terms (its
        other offered terms at the folds' mean), and where that is, as a refusal names it."""
        used = [loaded.term_names_.index(t) for t in loaded.terms_]
        centre = self.term_mean.mean(axis=0)
        centre[used] = 0.5 * (np.asarray(loaded.term_min_) + np.asarray(loaded.term_max_))
        points = [centre]
        for code in range(2 ** len(used)):
            point = centre.copy()
            for i, t in enumerate(used):
                point[t] = loaded.term_max_[i] if code >> i & 1 else loaded.term_min_[i]
            points.append(point)
        points = np.array(points)  # (P, T)
        held = np.clip(points[None], self.term_min[:, None, :], self.term_max[:, None, :])
        around = self.intercept[:, None] + np.einsum("spt,st->sp", held, self.coefficients)
        model = loaded.intercept_ + points[:, used] @ np.asarray(loaded.coef_)
        return around, model, "over the trained terms (log roughness at their centre and corners)"


def groove_folds(terms: np.ndarray, y: np.ndarray, specimens, contact_names) -> tuple[GrooveFolds | None,
                                                                                     np.ndarray]:
    """The model fitted without each specimen (order of first appearance), or None where a fold has no readable
    press (nothing to hold its terms to); and the specimens' codes."""
    terms = offered(terms)
    codes, _ = pd.factorize(pd.Series(np.asarray(specimens).astype(str)), sort=False)
    train = codes[None, :] != np.arange(int(codes.max()) + 1)[:, None]
    _, beta, centre = nested_fit(terms, np.log(np.asarray(y, dtype=np.float64))[:, None], train, specimens)
    low, high = fold_ranges(terms, train)
    if not (np.isfinite(low).all() and np.isfinite(high).all()):
        return None, codes
    slopes = beta[:, 1:, 0]
    means = fold_centres(terms, train, centre) + centre
    intercept = beta[:, 0, 0] - slopes @ centre
    return GrooveFolds(intercept, slopes, means, low, high, tuple(str(n) for n in contact_names)), codes


def groove_jackknife(X, y, specimens, contact: np.ndarray, contact_names, seed: int, surfaces=None):
    """The groove model's jackknife+ (each specimen's residual read from each kept count of presses), or None; the
    folds fitted as the model is, rows of one of ``surfaces`` read together."""
    terms, _ = contact_terms(contact, contact_names, surfaces)
    folds, _ = groove_folds(terms, y, specimens, contact_names)
    return None if folds is None else deploy(folds, X, y, specimens, seed, contact=contact)


def load_groove_folds(stored: dict, loaded, names: list, path: Path | None) -> GrooveFolds:
    """The file's folds, each checked as the deployed model's section is (ranges not empty, its means inside them,
    its exponent within 1e-6..1e6 over its term box)."""
    n, width = len(names), len(loaded.term_names_)
    intercept = fold_numbers(stored.get("intercept"), (n,), "folds.intercept", path)
    per_term = {name: fold_numbers(stored.get(name), (n, width), f"folds.{name}", path)
                for name in ("coefficients", "term_mean", "term_min", "term_max")}
    if np.any(per_term["term_min"] > per_term["term_max"]):
        raise ModelFileError(f"training.{KEY}.folds.term_min exceeds term_max: an empty training range", path=path)
    for i in range(n):
        try:
            _check_finite_predictions(float(intercept[i]), {k: v[i] for k, v in per_term.items()}, path)
        except ModelFileError as exc:
            raise ModelFileError(f"training.{KEY}.folds, fold {i + 1} ({names[i]}): {exc.message}", path=path) from None
    return GrooveFolds(intercept, per_term["coefficients"], per_term["term_mean"], per_term["term_min"],
                       per_term["term_max"], tuple(loaded.contact_names_))
