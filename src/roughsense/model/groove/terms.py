"""The groove model's terms: named physical contact measures of one press (or one trial's presses at its forces),
read from ``FoldSettings.contact``, in the fixed physical order a term is offered in (groove first).

Each row of ``contact`` holds the measures of sensor/contact_geometry.py at every force of the condition, block by
block (``MEASURE@CONDITION``: ``land_mm@1N``, ``groove_mm@1N``, ``land_mm@2N`` ...). The terms, all in logs (a
finger's roughness is a power law of the geometry, Lederman 1974):

- ``log_groove_mm``: the mean over forces of log groove (gap) width: what fingers feel first (Klatzky & Lederman 2007);
- ``log_land_mm``: the mean over forces of log land (contact) width (roughness falls a little with it);
- ``groove_change``: log groove width at the highest force less at the lowest (a combined condition only: how the
  pad sinks into the gap, which tells a rectangle from a circle at one period);
- ``log_contact_fraction``: the mean over forces of log(land / (land + groove)).

A width that cannot be read is NaN (never made up); a force whose width is NaN or not positive is left out of a
mean over forces, so a term is NaN only where no force of the row was read (``groove_change``: either end force).

**Surfaces.** Rows labelled as presses of one surface (``surfaces``) are read together, as the peak law reads them:
each measure is the geometric mean over the surface's presses where it was read. A fingerprint pad's widths are
read in about half its presses, and coarsely (to about a ridge period, sensor/contact_geometry.py), so one press
often gives no width, where ten presses of the surface give a mean; a press read alone keeps its own.
"""
from __future__ import annotations

import re

import numpy as np
import pandas as pd

from ...errors import ConfigError

LAND, GROOVE = "land_mm", "groove_mm"
#: Every term, in the order forward selection offers them (groove first).
TERM_NAMES = ("log_groove_mm", "log_land_mm", "groove_change", "log_contact_fraction")
#: What a user reads for each term (fit's report, the model file's reasons).
TERM_WORDS = {"log_groove_mm": "log groove width (mm)", "log_land_mm": "log land width (mm)",
              "groove_change": "change of log groove width from the lowest to the highest force",
              "log_contact_fraction": "log contact fraction"}
_FORCE = re.compile(r"^\s*([0-9]*\.?[0-9]+)\s*N\s*$", re.IGNORECASE)


def measure_columns(contact_names, measure: str) -> tuple[np.ndarray, tuple[str, ...]]:
    """The columns of ``measure`` (one per force block, in block order) and their conditions, or a refusal naming
    what is missing."""
    names = [str(n) for n in contact_names]
    found = [(i, n.partition("@")[2]) for i, n in enumerate(names) if n.partition("@")[0] == measure]
    if not found:
        raise ConfigError(f"the groove model reads the contact measure {measure!r}; the contact columns are "
                          f"{', '.join(names) or 'none'}")
    return np.array([i for i, _ in found]), tuple(c for _, c in found)


def force_order(conditions: tuple[str, ...]) -> np.ndarray:
    """The blocks' order by force (their labels' newtons where every label reads as ``<number>N``; else as given)."""
    forces = [_FORCE.match(c) for c in conditions]
    if all(forces):
        return np.argsort([float(m.group(1)) for m in forces], kind="stable")
    return np.arange(len(conditions))


def term_names(contact_names) -> tuple[str, ...]:
    """The terms these contact columns give: ``groove_change`` needs at least two forces."""
    _, conditions = measure_columns(contact_names, GROOVE)
    return tuple(t for t in TERM_NAMES if t != "groove_change" or len(conditions) > 1)


def _log_widths(contact: np.ndarray, columns: np.ndarray) -> np.ndarray:
    widths = contact[:, columns]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isfinite(widths) & (widths > 0), np.log(np.where(widths > 0, widths, 1.0)), np.nan)


def _mean_over_forces(values: np.ndarray) -> np.ndarray:
    finite = np.isfinite(values)
    count = finite.sum(axis=1)
    total = np.where(finite, values, 0.0).sum(axis=1)
    return np.divide(total, count, out=np.full(values.shape[0], np.nan), where=count > 0)


def surface_contact(contact: np.ndarray, surfaces=None) -> np.ndarray:
    """Each row's measures as its surface's: the geometric mean over the surface's rows where each was read (NaN
    where none was); ``surfaces`` None: each row its own."""
    if surfaces is None:
        return contact
    codes, _ = pd.factorize(pd.Series(np.asarray(surfaces).astype(str)), sort=False)
    if codes.size != contact.shape[0]:
        raise ConfigError(f"{codes.size} surface labels for {contact.shape[0]} rows of contact measures")
    with np.errstate(divide="ignore", invalid="ignore"):
        read = np.isfinite(contact) & (contact > 0)
        logs = np.where(read, np.log(np.where(read, contact, 1.0)), 0.0)
    total, count = np.zeros((codes.max() + 1, contact.shape[1])), np.zeros((codes.max() + 1, contact.shape[1]))
    np.add.at(total, codes, logs)
    np.add.at(count, codes, read)
    with np.errstate(divide="ignore", invalid="ignore"):
        pooled = np.where(count > 0, np.exp(total / np.maximum(count, 1)), np.nan)
    return pooled[codes]


def contact_terms(contact, contact_names, surfaces=None) -> tuple[np.ndarray, tuple[str, ...]]:
    """Each row's terms (n, T) as :func:`term_names` lists them (NaN: unreadable), and the names; the rows of one
    of ``surfaces`` read together (:func:`surface_contact`)."""
    contact = np.asarray(contact, dtype=np.float64)
    if contact.ndim != 2 or contact.shape[1] != len(contact_names):
        raise ConfigError(f"the contact measures (shape {contact.shape}) must hold one column per contact name "
                          f"({len(contact_names)})")
    contact = surface_contact(contact, surfaces)
    grooves, conditions = measure_columns(contact_names, GROOVE)
    lands, land_conditions = measure_columns(contact_names, LAND)
    if land_conditions != conditions:
        raise ConfigError(f"the contact columns give land widths at {', '.join(land_conditions)} but groove widths "
                          f"at {', '.join(conditions)}")
    log_groove, log_land = _log_widths(contact, grooves), _log_widths(contact, lands)
    with np.errstate(invalid="ignore"):
        log_fraction = log_land - np.logaddexp(log_land, log_groove)
    order = force_order(conditions)
    values = {"log_groove_mm": _mean_over_forces(log_groove), "log_land_mm": _mean_over_forces(log_land),
              "groove_change": log_groove[:, order[-1]] - log_groove[:, order[0]],
              "log_contact_fraction": _mean_over_forces(log_fraction)}
    names = term_names(contact_names)
    return np.column_stack([values[t] for t in names]), names
