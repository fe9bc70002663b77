"""Every run checks its scale: px/mm measured from structure of known period in the images it reads.

The structure is what the study already holds: a fingerprint pad's own ridges (``[pads.NAME] ridge_period_mm``) in
each of its presses, and its gratings of stated period (``wavelength_mm`` in specimens.csv: the reference R3 in every
study, and the others). The stated scale is never where the search starts: every scale at which a line resolves
its period is tried (``sensor/prominence.py``), so a check cannot be talked into agreeing.

**Agreement.** A scale is a candidate where most lines of one structure (:data:`MIN_SUPPORT`) and a good share of
every other's (:data:`MIN_SHARE`) show a clear peak (5x the line's noise floor) at the period that scale puts them,
and where lines of at least two different periods do (a pad's ridges and a grating; gratings of different periods).
Noise, photographs and bare background show a clear peak at one scale in a few lines at most, never in most lines of
two structures at once. A structure's harmonics make candidates at the true scale / k (a 3 mm grating's 3rd harmonic
sits where a 1 mm period would at a third of the scale), never at k times it: that would need a peak below the
fundamental, which a periodic image has not. So the largest candidate is the scale, unless a smaller one stands out by
more than :data:`~roughsense.model.scale_search.STRENGTH_MARGIN`. Two periods must agree wherever two are resolvable
(a short line resolves fewer). One known period alone (a fingerprint model's ridges, read on images of unknown
gratings) cannot tell its own fundamental from a grating that happens to sit there: it checks a stated scale inside,
or within :data:`~roughsense.sensor.period.CHECK_WINDOW` of, its largest candidate, and no other. Otherwise, or where
no scale is a candidate, the check says "scale could not be confirmed" and the stated scale is used.

**Reading.** At the chosen scale each line's period is measured below the DFT's bin within :data:`CHECK_WINDOW`
(``sensor/period.py``), about the stated scale where it lies among the scales the structures agree on, else about
the scale found; the median over the lines is the measured scale.

Tolerance (:data:`SCALE_TOLERANCE`, 1.5 %): a scale wrong by 10 % shifts the default model's predictions by 9-13 %, so
about 1 % per 1 % of scale; 1.5 % keeps the silent shift near the 2 % a user should never miss. A mount of the target
reads its period to the bench's mount-to-mount magnification (the twin's: 2.2 % SD; presses of one mount share it), so
the limit is never tighter than the 99 % t-interval over the mounts, and fewer than :data:`MIN_MOUNTS` mounts do not
make a check.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..sensor.period import ScaleMeasurement

#: Relative difference between measured and stated px/mm beyond which a run corrects or flags (module docstring).
SCALE_TOLERANCE = 0.015
#: What a corrected run's line says (the CLI shows such a line as a warning).
CORRECTED = "spectra read at the measured"
#: What every check that cannot vouch for the stated scale says, once, on stderr and in the report.
UNCONFIRMED = "scale could not be confirmed"
#: Mounts showing the known structure below which the scale is said to be unchecked.
MIN_MOUNTS = 3
#: The share of one structure's lines that must show a clear peak at a candidate scale: most of them. The twin's
#: presses at their true scale: every fingerprint press shows its ridges, every smooth-pad press its grating.
MIN_SUPPORT = 0.5
#: The share every other structure must show there: on the fingerprint pad the ridges outshine the gratings, whose own
#: period is clear in 30-100 % of a specimen's presses (BENCHMARKS.md, "scale check").
MIN_SHARE = 0.25


@dataclass(frozen=True)
class ScaleCheck:
    """The stated scale against the one measured from known structure (``sources``: what was measured, in words;
    ``doubt``: why the scale could not be confirmed, empty where it was)."""

    stated_px_per_mm: float
    sources: tuple[str, ...]
    measurement: ScaleMeasurement | None
    doubt: str = ""

    @property
    def checked(self) -> bool:
        return not self.doubt and self.measurement is not None and self.measurement.n_mounts >= MIN_MOUNTS

    @property
    def measured_px_per_mm(self) -> float:
        return self.measurement.px_per_mm if self.measurement is not None else math.nan

    @property
    def deviation(self) -> float:
        """Measured / stated - 1 (NaN when unchecked)."""
        return self.measured_px_per_mm / self.stated_px_per_mm - 1 if self.checked else math.nan

    @property
    def limit(self) -> float:
        """The tolerance this check can hold: :data:`SCALE_TOLERANCE`, or the 99 % t-interval's half-width over the
        mounts if wider (three mounts of one magnification each say little about the bench's spread)."""
        if not self.checked:
            return math.nan
        from scipy.stats import t

        error = self.measurement.standard_error
        if not math.isfinite(error):
            return SCALE_TOLERANCE
        return max(SCALE_TOLERANCE, float(t.ppf(0.995, self.measurement.n_mounts - 1)) * error)

    @property
    def off(self) -> bool:
        """True when the measured scale differs from the stated one by more than :attr:`limit`."""
        return self.checked and abs(self.deviation) > self.limit

    def summary(self) -> str:
        """One line: what was measured, from what, against what (or why the scale could not be confirmed)."""
        if not self.checked:
            why = self.doubt
            if not why:
                seen = 0 if self.measurement is None else self.measurement.n_mounts
                what = " or ".join(self.sources) if self.sources else ("a fingerprint pad's ridges or a specimen of "
                                                                       "stated period")
                why = f"{seen} mount(s) show {what} clearly (at least {MIN_MOUNTS} needed)"
            return f"{UNCONFIRMED}: {why}; {self.stated_px_per_mm:g} px/mm taken as stated"
        m = self.measurement
        return (f"scale: measured {m.px_per_mm:.4g} px/mm (+-{100 * m.standard_error:.2g} %, {m.n_measured} presses "
                f"in {m.n_mounts} mounts, "
                f"from {' and '.join(self.sources)}) against the stated {self.stated_px_per_mm:g} px/mm "
                f"({100 * self.deviation:+.1f} %; tolerance +-{100 * self.limit:.2g} %)")

    def correction(self) -> str:
        """The one line a run that corrects its scale prints (and its report keeps)."""
        return (f"{self.summary()}: {CORRECTED} {self.measured_px_per_mm:.4g} px/mm in place of study.toml's; "
                "run `roughsense calibrate` to measure and write it")

    def reason(self) -> str:
        """What a row flagged for its scale says (the ``outside`` column's words)."""
        return (f"scale: the images measure {self.measured_px_per_mm:.4g} px/mm, read at {self.stated_px_per_mm:g} "
                f"px/mm ({100 * self.deviation:+.1f} %)")


def check_study_lines(groups: list[tuple], stated_px_per_mm: float) -> ScaleCheck:
    """The scale check over ``groups`` of (source in words, period in mm, gray lines[, their mount labels]): groups of
    one source are one structure; a line without a label is a mount of its own (module docstring)."""
    from .scale_search import read_at, search

    entries = []  # (source, period, line, mount)
    for number, (source, period_mm, lines, *labels) in enumerate(groups):
        own = labels[0] if labels and labels[0] is not None else [f"{number}: line {i}" for i in range(len(lines))]
        entries.extend((source, float(period_mm), line, str(label)) for line, label in zip(lines, own))
    stated = float(stated_px_per_mm)
    if not entries:
        return ScaleCheck(stated, (), None)
    sources = tuple(dict.fromkeys(e[0] for e in entries))
    found = search(entries, stated)
    if found.doubt:
        return ScaleCheck(stated, sources, None, found.doubt)
    measurement = read_at(entries, found.centre(stated))
    return ScaleCheck(stated, sources, measurement)


#: Presses per known structure (a pad's ridges; each specimen) a study's check reads, spread over its mounts: a
#: mount's period is read to about the bench's magnification jitter, and the mounts of every specimen pool.
STUDY_PRESSES = 6
#: Specimen shapes whose wavelength_mm is a period the image repeats (a random surface's is a correlation length).
PERIODIC_SHAPES = ("rectangular", "circular", "sinusoidal")


def stated_periods(study) -> dict[str, float]:
    """Each periodic specimen's period (specimens.csv's wavelength_mm) that the band resolves (1-10 mm for the paper's
    band), by name: structure of known period in every study, the reference specimen's first."""
    table = study.specimens.set_index("specimen")
    ordered = [study.reference_specimen, *[s for s in table.index if s != study.reference_specimen]]
    return {s: float(table.loc[s, "wavelength_mm"]) for s in ordered if s in table.index
            and str(table.loc[s, "shape"]).lower() in PERIODIC_SHAPES and 1.0 <= table.loc[s, "wavelength_mm"] <= 10.0}


def check_study_scale(study, *, pad: str | None = None, presses: int = STUDY_PRESSES) -> ScaleCheck:
    """The study's stated scale against its pads' ridges (``pad``'s only, if given) and its specimens' stated periods."""
    from ..errors import ConfigError
    from ..sensor.spectrum import SpatialSpectrum

    reader = SpatialSpectrum(px_per_mm=study.sensor.px_per_mm, roi=study.sensor.roi,
                             max_pixels=study.sensor.max_pixels)
    try:
        reader.fit()
    except ConfigError:  # a scale the band cannot be read at: the analysis refuses it, naming study.toml
        return ScaleCheck(float(study.sensor.px_per_mm), (), None)
    manifest = study.manifest
    lines: dict[str, np.ndarray] = {}  # a press of R3 on a ridged pad is read for both structures: decoded once

    def line(image: str) -> np.ndarray:
        if image not in lines:
            lines[image] = reader.line(study.root / image)[0]
        return lines[image]

    def read(source: str, period: float, rows) -> tuple:
        """Presses spread over the mounts first (one per mount, then a second ...), up to ``presses``."""
        rows = rows.assign(mount=[f"{s}/{p}/{r}" for s, p, r in zip(rows["specimen"], rows["pad"], rows["repetition"])])
        order = rows.groupby("mount", sort=False).cumcount().sort_values(kind="stable").index
        picked = rows.loc[order[:presses]]
        return source, period, [line(image) for image in picked["image"]], list(picked["mount"])

    groups = []
    for name, ridge in study.pad_ridge_period_mm.items():
        if pad is None or name == pad:
            groups.append(read(f"the {name} pad's {ridge:g} mm ridges", ridge, manifest[manifest["pad"] == name]))
    mine = manifest[manifest["pad"] == pad] if pad else manifest
    for specimen, period in stated_periods(study).items():
        rows = mine[mine["specimen"] == specimen]
        if len(rows):
            groups.append(read("the specimens' periods in specimens.csv", period, rows))
    return check_study_lines(groups, float(study.sensor.px_per_mm))


def corrected(study, check: ScaleCheck):
    """The study read at the measured scale where the check found the stated one off, else the study as it is."""
    from dataclasses import replace

    if not check.off:
        return study
    return replace(study, sensor=replace(study.sensor, px_per_mm=round(check.measured_px_per_mm, 4)))
