"""The peak readout's fields in a model file, beneath both families' sections: their bounds (one home, as code
checks and as JSON Schema), the frequency grid the peak is read on, a log peak frequency on that grid, and the
training presses' scatter (``press_scatter``).

The peak law's section (model/peak_law/file.py) and a PLS file's peak readout domain (model/pls/file.py) both hold
these fields and check them here, so a value one accepts the other accepts too.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .._util.checks import Real, shown
from ..errors import ModelFileError
from ..io.numbers import BOUNDS
from ..sensor.grid import grid_step
from . import schema
from .peak_search import AGREEMENT_BINS, check_grid
from .press_spread import MAD_PER_SD, N_SPREAD, PressScatter
from .readout_domain import LOG_MARGIN

#: Largest magnitude of the law's numbers and of its features' range (log units; real fits are a few units).
LIMIT = 1e3
BOUNDED = Real(-LIMIT, LIMIT)
#: A clarity limit: the least clear trained peak (a log height above the band's median, so >= 0) less LOG_MARGIN; a
#: peak e^50 times its band's median is beyond any 8- or 16-bit image, so a limit above 50 would refuse everything.
CLARITY_LIMIT = Real(-LOG_MARGIN, 50.0)
#: A pad's ridge period: the range study.toml accepts (``io.numbers.BOUNDS``), so a law a study can train is loadable.
PAD_PERIOD = Real(BOUNDS["ridge_period_mm"].low, BOUNDS["ridge_period_mm"].high)
#: One number of the training presses' scatter (log units, >= 0; each column's limit is :func:`spread_limits`).
_SPREAD = Real(0.0)
#: How far either side of a pad's ridge frequency a peak search may leave out (mm^-1).
EXCLUSION = Real(0.0, 10.0, low_open=True)


def bounded(constraint: Real, *, null: bool = False, **more) -> dict:
    """A :class:`Real` constraint as a JSON Schema node (the same bounds, one home)."""
    node = schema.number(constraint.low, constraint.high, null=null, **more)
    if constraint.low_open:
        node["exclusiveMinimum"] = node.pop("minimum")
    return node


#: The press scatter (model/press_spread.py); each spread's limit, which depends on the grid, is checked in code.
PRESS_SCATTER_SCHEMA = schema.strict({
    "spread": {"type": "array", "items": schema.number(0.0), "minItems": N_SPREAD, "maxItems": N_SPREAD},
    "trained_presses": schema.number(1.0, BOUNDS["repetition"].high),
}, required=("spread", "trained_presses"))


def press_scatter(section: dict, where: str, freq: np.ndarray, path: Path | None) -> PressScatter | None:
    """The section's ``press_scatter`` ({"spread": 4 numbers >= 0, "trained_presses": a count >= 1}), or None where
    the file predates it (or the law was fitted without surfaces); each spread within :func:`spread_limits`."""
    if "press_scatter" not in section:
        return None
    value = section["press_scatter"]
    spread = value.get("spread") if isinstance(value, dict) else None
    count = value.get("trained_presses") if isinstance(value, dict) else None
    if not isinstance(value, dict) or set(value) != {"spread", "trained_presses"} or not isinstance(spread, list) \
            or len(spread) != N_SPREAD or not all(_SPREAD.accepts(v) for v in spread) \
            or not Real(1.0, BOUNDS["repetition"].high).accepts(count):
        raise ModelFileError(f"{where}.press_scatter must be {{\"spread\": {N_SPREAD} numbers >= 0, \"trained_presses\": "
                             f"a count of presses >= 1}}, got {shown(value)}", path=path)
    for i, (number, limit) in enumerate(zip(spread, spread_limits(freq))):
        if number > limit:
            raise ModelFileError(f"{where}.press_scatter.spread[{i}] is {shown(number)}; a fit gives at most "
                                 f"{limit:.4g} (robust SD of {SPREAD_NAMES[i]})", path=path)
    return PressScatter(np.array(spread, dtype=np.float64), float(count))


#: What each spread is the robust SD of (model/press_spread.py).
SPREAD_NAMES = ("a press's log peak frequency", "its log peak amplitude", "its second-harmonic ratio",
                "its peak's clarity")


def spread_limits(freq: np.ndarray) -> np.ndarray:
    """The largest spread a fit gives, per column: the robust SD is the median absolute deviation of every training
    press from its surface's reading, / 0.6745. A press that agrees with its surface on where the peak is (within
    AGREEMENT_BINS bins, as a surface's presses must mostly agree for its reading to stand) reads a log frequency
    within log(1 + AGREEMENT_BINS step / (f_lowest - step / 2)) of it, so a median over presses most of which agree
    lies within that (0.44 on the default grid; real spreads: 0.01-0.05). The amplitude, shape and clarity are log
    heights of one 8- or 16-bit image's spectrum, which differ by less than CLARITY_LIMIT's e^50 (an edited spread
    of 1000 would switch every flag off)."""
    step = grid_step(freq)
    lowest = float(freq[0]) - 0.5 * step if freq.size > 1 else float(freq[0])
    period = math.log1p(AGREEMENT_BINS * step / max(lowest, 1e-12)) / MAD_PER_SD
    heights = CLARITY_LIMIT.high / MAD_PER_SD
    return np.array([period, heights, heights, heights])


def spectrum_grid(spectrum: dict, path: Path | None) -> np.ndarray:
    """The spectrum's frequencies (mm^-1): the grid the peak is located on, so it must be a real, even grid."""
    freq = spectrum.get("freq_per_mm")
    n_freqs = spectrum["n_freqs"]
    if not isinstance(freq, list) or len(freq) != n_freqs or not all(Real(0.0, LIMIT, low_open=True).accepts(f)
                                                                     for f in freq):
        raise ModelFileError(f"features.spectrum.freq_per_mm must be {n_freqs} positive frequencies (mm^-1)", path=path)
    try:
        return check_grid(freq, min_bins=1)  # the estimator's own rule for a grid the peak can be located on
    except ValueError:
        raise ModelFileError("features.spectrum.freq_per_mm must be evenly spaced and increasing", path=path) from None


def check_log_frequencies(values, freq: np.ndarray, where: str, path: Path | None) -> None:
    """A peak is read on the grid (to within half a bin), so a stored log peak frequency outside the grid's range
    is no fitted value; refused here, before the domain's margins divide by exp() of it and overflow."""
    step = grid_step(freq)
    low = math.log(max(float(freq[0]) - step, 0.5 * float(freq[0])))
    high = math.log(float(freq[-1]) + step)
    if not all(low <= float(v) <= high for v in values):
        raise ModelFileError(f"{where} (log peak frequency) must lie within the grid's {low:.4g} to {high:.4g}, got "
                             f"{shown([float(v) for v in values])}", path=path)
