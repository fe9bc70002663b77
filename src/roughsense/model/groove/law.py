"""The groove model: perceived roughness as a power law of the contact's geometry, the terms chosen by nested
leave-one-specimen-out.

Why. People feel the groove: roughness grows with groove width, falls a little with land width and grows with force
(Lederman 1974); groove width alone predicts most of it (Klatzky & Lederman 2007). The paper's gratings are half
and half, so a model of the period learned the groove by proxy and misreads a grating whose land and groove differ.
This model reads the widths themselves (sensor/contact_geometry.py, per press), in logs::

    log(roughness) = b0 + sum over the chosen terms of b_t * term_t

the terms (model/groove/terms.py) offered in a fixed physical order, groove first, each kept only where it lowers
the inner leave-one-specimen-out error by more than one standard error (model/groove/cv.py); none kept: the
training mean of log roughness. Least squares, not Huber: the terms are few, every fit and every nested choice of
every fold and shuffling is then exact from sums (a robust fit would make the nesting an IRLS per subset per fold),
and an unreadable width is NaN (left out), not a wild number. A term is held to its training range when predicting
(a power law is not carried past its data); the domain (model/groove/domain.py) flags what lies outside.

It reads no spectrum: ``X`` (the spectra) only fixes the width a model file's rows have; ``contact`` (n, k) holds
each row's measures in the order of ``contact_names``.
"""
from __future__ import annotations

from typing import ClassVar

import numpy as np

from ...errors import InputError
from ..loaded import FromModelFile
from ..registry import GROOVE as NAME  # the family's name, beside its class
from .cv import SELECTION_SE, nested_fit, offered
from .domain import AXES, axis_values, domain_reasons, trained_box
from .terms import TERM_WORDS, contact_terms


class GrooveInputError(InputError, ValueError):
    """Contact measures that do not match the model (missing, of another width); also a ValueError."""


class GrooveLaw(FromModelFile):
    """Regressor: contact measures (n, k) -> perceived roughness, a power law of the chosen contact terms.

    Fitted: ``contact_names_`` (the columns it reads, in order), ``term_names_`` (every term offered),
    ``terms_`` (those chosen, in order), ``intercept_``, ``coef_`` (one per chosen term), ``term_mean_`` (each
    chosen term's training mean: where an unreadable one is put), ``term_min_``/``term_max_`` (its training range),
    ``domain_low_``/``domain_high_``/``domain_margin_`` (log groove and log land width: model/groove/domain.py),
    ``n_features_in_`` (the spectra's width).
    """

    family: ClassVar[str] = NAME

    def __init__(self, selection_se: float = SELECTION_SE) -> None:
        self.selection_se = selection_se

    def fit(self, X, y, *, contact, contact_names, specimens, surfaces=None) -> GrooveLaw:
        """Choose the terms by leave-one-specimen-out over ``specimens`` and fit them on every row; rows of one of
        ``surfaces`` are read together (model/groove/terms.py)."""
        every_term, names = contact_terms(contact, contact_names, surfaces)
        terms = offered(every_term)
        y = np.asarray(y, dtype=np.float64)
        if y.shape != (terms.shape[0],) or not np.all(np.isfinite(y) & (y > 0)):
            raise GrooveInputError("perceived roughness must be one positive number per row of the contact measures")
        if not np.isfinite(axis_values(every_term, names)).all(axis=1).any():
            raise GrooveInputError("no press has readable land and groove widths; the groove model has nothing to fit")
        every = np.ones((1, y.size), dtype=bool)
        chosen, beta, centre = nested_fit(terms, np.log(y)[:, None], every, specimens, self.selection_se)
        used = np.array([t for t in range(len(names)) if chosen[0, 0] >> t & 1], dtype=np.intp)
        readable = np.all(np.isfinite(terms), axis=1)
        self.n_features_in_ = int(np.shape(X)[1])
        self.contact_names_, self.term_names_ = tuple(str(n) for n in contact_names), names
        self.terms_ = tuple(names[t] for t in used)
        self.coef_ = beta[0, 1 + used, 0]
        self.intercept_ = float(beta[0, 0, 0] - self.coef_ @ centre[used])
        self.term_mean_ = terms[readable][:, used].mean(axis=0) if readable.any() else np.zeros(used.size)
        self.term_min_ = terms[readable][:, used].min(axis=0) if readable.any() else np.zeros(used.size)
        self.term_max_ = terms[readable][:, used].max(axis=0) if readable.any() else np.zeros(used.size)
        codes = np.unique(np.asarray(specimens).astype(str), return_inverse=True)[1].ravel()
        self.domain_low_, self.domain_high_, self.domain_margin_ = trained_box(
            axis_values(every_term, names), codes, np.ones(y.size, dtype=bool))
        return self

    def _terms(self, X, contact, surfaces=None) -> np.ndarray:
        """Every offered term of each row (n, T), after refusing contact measures that are not the model's."""
        X = self._file_inputs(X)
        if contact is None:
            raise GrooveInputError(f"the groove model reads contact measures ({', '.join(self.contact_names_)}); "
                                   "none were given")
        try:
            contact = np.asarray(contact, dtype=np.float64)
        except (TypeError, ValueError):
            raise GrooveInputError("the contact measures must be numbers (NaN where a width was not read)") from None
        if contact.ndim != 2 or contact.shape != (len(X), len(self.contact_names_)):
            raise GrooveInputError(f"the groove model reads {len(self.contact_names_)} contact measure(s) per row "
                                   f"({', '.join(self.contact_names_)}) for {len(X)} row(s), got shape "
                                   f"{contact.shape}")
        return contact_terms(contact, self.contact_names_, surfaces)[0]

    def predict(self, X, surfaces=None, contact=None) -> np.ndarray:
        """Perceived roughness of each row; rows of one of ``surfaces`` are read together (their widths' geometric
        mean where read), a row without a surface alone."""
        terms = self._terms(X, contact, surfaces)
        chosen = terms[:, [self.term_names_.index(t) for t in self.terms_]]
        held = np.clip(np.where(np.isfinite(chosen), chosen, self.term_mean_), self.term_min_, self.term_max_)
        return np.exp(self.intercept_ + held @ self.coef_)

    def applicability(self, X, surfaces=None, contact=None) -> list[str]:
        """Per row, what lies outside the land and groove widths it was trained on ('' where nothing does)."""
        terms = self._terms(X, contact, surfaces)
        reasons = domain_reasons(axis_values(terms, self.term_names_), self.domain_low_, self.domain_high_,
                                 self.domain_margin_)
        other = [t for t in self.terms_ if t not in AXES]  # a chosen term beyond the axes, unread: put at its mean
        for row, reason in enumerate(reasons):
            unread = [TERM_WORDS[t] for t in other if not np.isfinite(terms[row, self.term_names_.index(t)])]
            reasons[row] = "; ".join([r for r in (reason, *(f"{w} unreadable in this press" for w in unread)) if r])
        return reasons

    def extrapolates(self, X, surfaces=None, contact=None) -> np.ndarray:
        return np.array([bool(r) for r in self.applicability(X, surfaces, contact)], dtype=bool)

    def equation(self) -> str:
        """The fitted law in words, as ``fit`` prints it."""
        parts = [f"{self.intercept_:.4f}"] + [f"{c:+.4f} {TERM_WORDS[t]}" for t, c in zip(self.terms_, self.coef_)]
        return "log(roughness) = " + " ".join(parts) + ("" if self.terms_ else " (no term earned its place)")
