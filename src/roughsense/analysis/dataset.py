"""A study as regression data: spectra (X) per pad and force condition, perceived roughness (y).

One row per image in :func:`study_features`; :func:`condition_matrix` selects a pad and a condition, and for
"combined" puts a trial's 1 N, 2 N and 3 N spectra side by side (3 x 45 predictors, as in the paper);
:func:`targets` maps each row's specimen to the perceived roughness (the geometric mean of the ratings).
"""
from __future__ import annotations

import os
from collections.abc import Callable, Sequence

import numpy as np
import pandas as pd

from ..errors import ConfigError, InputError
from ..io.study import MANIFEST_CSV, RATINGS_CSV, STUDY_TOML, Study
from ..paper import COMBINED, FORCE_CONDITIONS
from .magnitude_estimation import aggregate_ratings

TRIAL_KEYS = ("specimen", "pad", "repetition")
#: The analysis's own mark on a spectrum column (``spectrum@0.1`` holds the amplitude at 0.1 mm^-1). Spectrum
#: columns are found by this mark, never by parsing headers: a manifest column named ``0.1`` or ``nan`` stays a
#: manifest column. Files written for people (``features``, the report) use the bare frequency (:func:`plain_names`).
SPECTRUM_PREFIX = "spectrum@"
#: The mark on a contact measure's column (``contact@groove_mm``: sensor/contact_geometry.py's CONTACT_MEASURES), one
#: per measure beside the spectrum; files written for people use the bare measure's name (:func:`plain_names`).
CONTACT_PREFIX = "contact@"


def spectrum_columns(freq_per_mm) -> list[str]:
    """The feature table's column of each frequency (mm^-1): the prefix and the shortest round-tripping decimal."""
    return [f"{SPECTRUM_PREFIX}{float(f)!r}" for f in freq_per_mm]


def contact_columns() -> list[str]:
    """The feature table's column of each contact measure, in CONTACT_MEASURES' order."""
    from ..sensor.contact_geometry import CONTACT_MEASURES

    return [f"{CONTACT_PREFIX}{name}" for name in CONTACT_MEASURES]


def column_frequencies(columns: Sequence[str]) -> np.ndarray:
    """The frequency (mm^-1) of each spectrum column, read back from the names :func:`spectrum_columns` made."""
    return np.array([float(str(c)[len(SPECTRUM_PREFIX):]) for c in columns], dtype=np.float64)


def plain_names(table: pd.DataFrame, *, source=None) -> pd.DataFrame:
    """``table`` with each spectrum column named by its bare frequency (``0.1``) and each contact column by its bare
    measure (``land_mm``), as files for people show them.

    A column already named so would make two columns of one name: refused, naming it.
    """
    marked = [c for c in table.columns if isinstance(c, str) and c.startswith((SPECTRUM_PREFIX, CONTACT_PREFIX))]
    plain = {c: c.split("@", 1)[1] for c in marked}
    clash = next((str(c) for c in table.columns if c not in plain and str(c) in plain.values()), None)
    if clash is not None:
        raise InputError(f"column {clash!r} has the name of a spectrum frequency or a contact measure; rename it",
                         path=source)
    return table.rename(columns=plain)


def spectrum_for(study: Study, *, n_jobs: int = 1):
    """The SpatialSpectrum configured from the study's sensor settings (camera scale and ROI)."""
    from ..sensor.spectrum import SpatialSpectrum

    try:
        return SpatialSpectrum(px_per_mm=study.sensor.px_per_mm, roi=study.sensor.roi, n_jobs=n_jobs,
                               max_pixels=study.sensor.max_pixels).fit()
    except ConfigError as exc:  # the settings came from study.toml's [sensor]: say so (e.g. below Nyquist)
        raise InputError(f"[sensor] {exc.message}", path=study.root / STUDY_TOML) from None


def study_features(
    study: Study, *, n_jobs: int = 1, progress: Callable | None = None, spectrum=None
) -> pd.DataFrame:
    """Manifest columns, one column per grid frequency (:func:`spectrum_columns`), then one per contact measure
    (:func:`contact_columns`: land and groove widths, NaN where a press's cannot be read).

    Each image is read once for both; a pad's ridges (``study.pad_ridge_period_mm``) decide how its contact is read.
    ``progress(iterable, total=, description=)`` wraps the image stream (the CLI passes a rich bar).
    ``spectrum`` overrides the study's own sensor settings (a fitted SpatialSpectrum).
    """
    marked = [str(c) for c in study.manifest.columns if str(c).startswith((SPECTRUM_PREFIX, CONTACT_PREFIX))]
    if marked:  # before any image is read
        prefix = SPECTRUM_PREFIX if marked[0].startswith(SPECTRUM_PREFIX) else CONTACT_PREFIX
        raise InputError(f"column {marked[0]!r} starts with {prefix!r}, which marks roughsense's "
                         f"{prefix.rstrip('@')} columns; rename it", path=study.root / MANIFEST_CSV)
    spectrum = spectrum if spectrum is not None else spectrum_for(study, n_jobs=n_jobs)
    paths = study.image_paths
    names, contact_names = spectrum_columns(spectrum.freq_per_mm_), contact_columns()
    X, contact = np.empty((len(paths), len(names))), np.empty((len(paths), len(contact_names)))
    rows = _readings_by_pad(study, spectrum, paths)
    if progress is not None:
        rows = progress(rows, total=len(paths), description="spectra")
    for i, row, measures in rows:
        X[i], contact[i] = row, measures
    read = pd.DataFrame(np.hstack([X, contact]), columns=[*names, *contact_names])
    return pd.concat([study.manifest.reset_index(drop=True), read], axis=1)


def _readings_by_pad(study: Study, spectrum, paths):
    """(row, spectrum, contact measures) of every image, pad by pad (a pad's ridge period reads its contact)."""
    pads = study.manifest["pad"].astype(str).to_numpy() if len(paths) else np.empty(0, dtype=str)
    for pad in dict.fromkeys(pads.tolist()):
        rows = np.flatnonzero(pads == pad)
        readings = spectrum.iter_transform_contact([paths[i] for i in rows], study.pad_ridge_period_mm.get(pad))
        for i, (row, measures) in zip(rows.tolist(), readings):
            yield i, row, measures


def check_repetitions(features: pd.DataFrame, study: Study) -> None:
    """Cross-validation needs at least 2 images of each specimen on each pad at each force."""
    counts = features.groupby(["pad", "specimen", "condition"]).size()
    if counts.min() < 2:
        (pad, specimen, condition) = counts.idxmin()
        raise InputError(
            f"too few repetitions for cross-validation: {specimen} on the {pad} pad at {condition} has {counts.min()}",
            path=study.root / MANIFEST_CSV,
        )


def frequency_columns(features: pd.DataFrame) -> list[str]:
    """The spectrum columns (those :func:`spectrum_columns` named), in order."""
    return [c for c in features.columns if isinstance(c, str) and c.startswith(SPECTRUM_PREFIX)]


def conditions_of(condition: str, available: Sequence[str] = FORCE_CONDITIONS) -> list[str]:
    """The force conditions a model condition uses: ["2N"] for "2N", all three for "combined"."""
    if condition == COMBINED:
        return list(available)
    return [condition]


def condition_matrix(
    features: pd.DataFrame, pad: str, condition: str, *, source=None, combined_forces: Sequence[str] | None = None
) -> tuple[np.ndarray, pd.DataFrame]:
    """(X, meta) for one pad and condition ("1N", "2N", "3N" or "combined").

    For "combined", each trial (specimen, pad, repetition) contributes one row: its 1 N, 2 N and 3 N
    spectra concatenated in that order. A trial missing a force (or holding two images of one) is refused.
    ``meta`` has specimen, repetition and image (or image_1N, image_2N, image_3N for "combined").
    ``source`` (e.g. the manifest's path) is named in errors. ``combined_forces`` (condition labels, in order)
    replaces the paper's 1N, 2N, 3N in "combined" (a protocol with other or more forces).
    """
    freq = frequency_columns(features)
    if not freq:
        raise InputError("the feature table has no spectrum columns")
    for column in ("pad", "condition", *TRIAL_KEYS, "image"):
        if column not in features.columns:
            raise InputError(f"the feature table lacks the column {column!r}")
    at_pad = features[features["pad"].astype(str) == str(pad)]
    if at_pad.empty:
        pads = ", ".join(sorted(map(str, features["pad"].unique())))
        raise InputError(f"no images of pad {pad!r} (pads in the study: {pads})", path=source)
    if condition != COMBINED:
        return _single_force_matrix(at_pad, freq, pad, condition, source)
    forces = list(combined_forces) if combined_forces is not None else list(FORCE_CONDITIONS)
    return _combined_matrix(at_pad, freq, pad, forces, source)


def _single_force_matrix(at_pad: pd.DataFrame, freq: list[str], pad: str, condition: str, source
                         ) -> tuple[np.ndarray, pd.DataFrame]:
    """One row per image at ``condition``, in specimen, repetition, image order."""
    present = sorted(map(str, at_pad["condition"].unique()), key=_force_order)
    if condition not in FORCE_CONDITIONS and condition not in present:
        raise InputError(f"unknown condition {condition!r}; expected 1N, 2N, 3N or combined", path=source)
    rows = at_pad[at_pad["condition"] == condition]
    if rows.empty:
        raise InputError(
            f"no images of pad {pad!r} at {condition} (conditions present: {', '.join(present)})", path=source
        )
    rows = rows.sort_values(["specimen", "repetition", "image"], kind="stable")
    meta = rows[["specimen", "repetition", "image"]].reset_index(drop=True)
    return rows[freq].to_numpy(np.float64), meta


def _combined_matrix(at_pad: pd.DataFrame, freq: list[str], pad: str, forces: list[str], source
                     ) -> tuple[np.ndarray, pd.DataFrame]:
    """One row per trial: its spectra at ``forces`` side by side; a trial missing a force or holding two is refused."""
    rows = at_pad[at_pad["condition"].isin(forces)]
    if rows.empty:
        raise InputError(f"no images of pad {pad!r} at {', '.join(forces)} for the combined condition", path=source)
    counts = rows.groupby(["specimen", "repetition", "condition"]).size()
    doubled = counts[counts > 1]
    if not doubled.empty:
        specimen, repetition, force = doubled.index[0]
        raise InputError(
            f"combined condition: specimen {specimen!r}, repetition {repetition} on pad {pad!r} has "
            f"{doubled.iloc[0]} images at {force}; a trial needs exactly one image per force",
            path=source,
        )
    wide = rows.pivot(index=["specimen", "repetition"], columns="condition", values="image")
    for trial, images in wide.iterrows():
        missing = [f for f in forces if f not in images.index or pd.isna(images[f])]
        if missing:
            specimen, repetition = trial
            raise InputError(
                f"combined condition: specimen {specimen!r}, repetition {repetition} on pad {pad!r} has no "
                f"image at {', '.join(missing)}; every trial needs {', '.join(forces)}",
                path=source,
            )
    wide = wide.sort_index()
    by_image = rows.set_index("image")[freq]
    blocks = [by_image.loc[wide[f].to_numpy()].to_numpy(np.float64) for f in forces]
    meta = wide.reset_index()[["specimen", "repetition"]].copy()
    for f in forces:
        meta[f"image_{f}"] = wide[f].to_numpy()
    from ..sensor.spectrum import combine_forces

    return combine_forces(blocks), meta


def condition_contact(features: pd.DataFrame, meta: pd.DataFrame, condition: str,
                      combined_forces: Sequence[str] | None = None) -> tuple[np.ndarray | None, tuple[str, ...]]:
    """Each row of :func:`condition_matrix`'s ``meta``: its images' contact measures, force block by force block as
    its spectra (``groove_mm@1N``, ...), and their names; (None, ()) where the table holds no contact measures.

    The rows are found by image, so they line up with the spectra whatever order the table is in."""
    columns = [c for c in contact_columns() if c in features.columns]
    if not columns:
        return None, ()
    by_image = features.set_index(features["image"].astype(str))[columns]
    if condition == COMBINED:
        forces = list(combined_forces) if combined_forces is not None else list(FORCE_CONDITIONS)
        images = [(f, meta[f"image_{f}"]) for f in forces]
    else:
        images = [(condition, meta["image"])]
    blocks = [by_image.loc[column.astype(str).to_numpy()].to_numpy(np.float64) for _, column in images]
    names = tuple(f"{c[len(CONTACT_PREFIX):]}@{force}" for force, _ in images for c in columns)
    return np.hstack(blocks), names


def _force_order(label: str) -> float:
    try:
        return float(label.rstrip("N"))
    except ValueError:
        return float("inf")


def targets(meta: pd.DataFrame, summary: pd.DataFrame, *, path: str | os.PathLike[str] | None = None) -> np.ndarray:
    """Perceived roughness (``gmean``) of each row's specimen; a specimen without ratings is refused.

    ``path`` (the ratings file ``summary`` came from, e.g. ``study.root / "ratings.csv"``) only labels errors.
    """
    if "specimen" not in summary.columns or "gmean" not in summary.columns:
        raise InputError("the perceived-roughness table needs columns specimen and gmean", path=path)
    lookup = dict(zip(summary["specimen"].astype(str), summary["gmean"].astype(float)))
    specimens = meta["specimen"].astype(str)
    missing = sorted(set(specimens) - set(lookup))
    if missing:
        raise InputError(f"no perceived roughness for specimen(s) {', '.join(missing)} (not in the ratings)", path=path)
    y = specimens.map(lookup).to_numpy(np.float64)
    if not np.all(np.isfinite(y)):
        bad = specimens[~np.isfinite(y)].iloc[0]
        raise InputError(f"perceived roughness of specimen {bad!r} is not a finite number", path=path)
    return y


def perceived_roughness(study: Study) -> pd.DataFrame:
    """Aggregate the study's ratings (median over sessions, geometric mean over participants)."""
    if study.ratings is None:
        raise InputError("file not found (fitting a model needs participants' ratings)", path=study.root / RATINGS_CSV)
    return aggregate_ratings(study.ratings, reference=study.reference_specimen, path=study.root / RATINGS_CSV)
