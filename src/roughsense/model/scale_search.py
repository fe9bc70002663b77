"""The scale check's search: every resolvable scale tried, the largest on which structures of different known periods
agree chosen, and each line's period read there (the reasoning is ``model/scale_check.py``'s docstring).

An entry is (source in words, period in mm, gray line, mount label); entries of one source are one structure (a
pad's ridges; the study's gratings of stated period, each line at its own period).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..sensor.period import CHECK_WINDOW, ScaleMeasurement, check_scale
from ..sensor.prominence import CLEAR_PROMINENCE, LineSpectrum, peak_heights, scale_grid

#: Harmonics make candidates below the true scale, as strong as a square wave's 3rd harmonic is (a third of the
#: fundamental) or as a pulse train's (nearly as strong), never above it: the largest candidate is taken unless a
#: smaller one stands out by more than this (log of summed median prominences; a larger one read from another
#: structure lacks whole structures' strength, e.g. a ridged pad's ridges read at 3x the scale on a 3 mm grating).
STRENGTH_MARGIN = float(np.log(3.0))


@dataclass(frozen=True)
class Found:
    """The scale the structures agree on (NaN with a ``doubt``: why there is none to trust)."""

    px_per_mm: float
    doubt: str = ""
    low: float = np.nan
    high: float = np.nan

    def centre(self, stated_px_per_mm: float) -> float:
        """Where each line's period is read: about the stated scale where it lies among the scales the structures
        agree on (the reading every run made before this search, unchanged), else about the scale found."""
        return float(stated_px_per_mm) if self.low <= stated_px_per_mm <= self.high else self.px_per_mm


def _spectra(entries) -> dict[int, LineSpectrum]:
    """Each distinct line's spectrum, once (a press of R3 on a ridged pad is read for both structures)."""
    out: dict[int, LineSpectrum] = {}
    for _, _, line, _ in entries:
        if id(line) not in out:
            out[id(line)] = LineSpectrum.of(line)
    return out


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of True."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def _support(entries, spectra, scales) -> tuple[np.ndarray, np.ndarray]:
    """(candidate mask, strength) over ``scales``: a candidate where one structure shows clear peaks in most of its
    lines that resolve it there (MIN_SUPPORT), every other in at least MIN_SHARE of them, and clear lines of two
    periods (or of the one period given) agree; the strength is the structures' summed
    median log prominence (a fundamental stands above the harmonics that alias it)."""
    from .scale_check import MIN_SHARE, MIN_SUPPORT

    periods = sorted({e[1] for e in entries})
    ok, most = np.ones(scales.size, dtype=bool), np.zeros(scales.size, dtype=bool)
    strength = np.zeros(scales.size)
    periods_clear = np.zeros((len(periods), scales.size), dtype=bool)
    for source in dict.fromkeys(e[0] for e in entries):
        logs = []
        for _, period, line, _ in (e for e in entries if e[0] == source):
            height, resolvable = peak_heights(spectra[id(line)], period, scales)
            periods_clear[periods.index(period)] |= height >= CLEAR_PROMINENCE
            logs.append(np.where(resolvable, np.log(np.maximum(height, 1.0)), np.nan))
        logs = np.asarray(logs)
        resolvable_sum = np.isfinite(logs).sum(axis=0)
        share = np.divide((logs >= np.log(CLEAR_PROMINENCE)).sum(axis=0), resolvable_sum,
                          out=np.zeros(scales.size), where=resolvable_sum > 0)
        ok &= (resolvable_sum == 0) | (share >= MIN_SHARE)
        most |= share >= MIN_SUPPORT
        with warnings.catch_warnings():  # a scale no line of the structure resolves: all-NaN, no strength
            warnings.simplefilter("ignore", RuntimeWarning)
            strength += np.nan_to_num(np.nanmedian(logs, axis=0), nan=0.0)
    return ok & most & (periods_clear.sum(axis=0) >= min(2, len(periods))), strength


def search(entries, stated_px_per_mm: float) -> Found:
    """The largest scale the structures agree on whose strength is within :data:`STRENGTH_MARGIN` of the strongest,
    at the middle of its strongest plateau (module docstring)."""
    spectra = _spectra(entries)
    scales = scale_grid([e[1] for e in entries], [spectra[id(e[2])].line_px for e in entries])
    ok, score = _support(entries, spectra, scales)
    runs = _runs(ok)
    sources = " and ".join(dict.fromkeys(e[0] for e in entries))
    if not runs:
        return Found(np.nan, f"no scale puts a clear peak (over {CLEAR_PROMINENCE:g}x the line's noise floor) at "
                             f"the known period in most presses of {sources}")
    peaks = [float(score[a:b].max()) for a, b in runs]
    top = max(i for i in range(len(runs)) if peaks[i] >= max(peaks) - STRENGTH_MARGIN)
    start, stop = runs[top]
    best = start + np.flatnonzero(score[start:stop] == peaks[top])
    chosen = float(np.sqrt(scales[best[0]] * scales[best[-1]]))
    stated = float(stated_px_per_mm)
    inside = [scales[a] <= stated <= scales[b - 1] for a, b in runs]
    near = inside[top] or (not any(inside) and abs(stated / chosen - 1) <= CHECK_WINDOW)
    if len({e[1] for e in entries}) == 1 and not near:
        strongest = sorted(range(len(runs)), key=lambda i: -peaks[i])[:3]
        where = " or ".join(f"{np.sqrt(scales[runs[i][0]] * scales[runs[i][1] - 1]):.4g}" for i in strongest)
        return Found(np.nan, f"{sources} alone show clear peaks at {where} px/mm"
                             f"{', the stated scale among them' if any(inside) else f', not at the stated {stated:g}'}"
                             "; one known period can check a scale near the stated one, not find it")
    return Found(chosen, "", float(scales[start]), float(scales[stop - 1]))


def read_at(entries, px_per_mm: float) -> ScaleMeasurement:
    """Each line's own px/mm within :data:`CHECK_WINDOW` of ``px_per_mm`` (``sensor.period.check_scale``), the mounts
    labelled."""
    each = [float(check_scale([line], period, px_per_mm, window=CHECK_WINDOW).px_per_mm_each[0])
            for _, period, line, _ in entries]
    mounts = np.asarray([e[3] for e in entries], dtype=object)
    return ScaleMeasurement(np.nan, np.asarray(each, dtype=np.float64), mounts)
