"""The contact-image gate: is this a contact image of the model's pad on the model's rig? A conformal novelty test.

``fit`` learns from its own training presses what one looks like, in the descriptors of ``sensor/descriptors.py``
(standardised: logs of the positive ones, centred on their medians, scaled by their IQRs). The score of a press is its
squared Mahalanobis distance under a shrunk covariance (scikit-learn's ``LedoitWolf``: well conditioned with ten
presses a specimen and eight descriptors, deterministic, and fast enough to fit once per held-out specimen; the
standardisation before it is the robust part); the p-value is conformal (Bates et al., Ann. Statist. 2023, "Testing for
outliers with conformal p-values"), calibrated over specimens, not presses:

* presses of one specimen are alike (one grating, one mount series), so a press is not exchangeable with held-out
  copies of its own specimen. Each specimen is held out in turn: a detector fitted on the others' presses scores its
  presses (the calibration scores), and a new press is scored by that same detector;
* the p-value of a new press x is the cross-conformal one, p(x) = (1 + #{i : s_g(i)(x) >= s_g(i)(x_i)}) / (n + 1),
  each calibration press compared under the detector that never saw its specimen. A new specimen's press is then
  exchangeable with a held-out specimen's, and P(p <= alpha) <= alpha up to the cross-conformal slack.

This group calibration is the only part written here: no library does it with this group structure. A press whose
p is at most ``alpha`` (1 %, stored in the model file) is withheld, with a reason naming the descriptors that lie
furthest outside their training ranges, in the user's words. A combined-force model's trial is withheld when any of
its k images is, each at alpha / k (Bonferroni), so a trial's false-alarm rate stays at most alpha.

The grating's orientation is not a gate input: beyond :data:`ORIENTATION_TOLERANCE_DEG` the press is flagged (see
:func:`orientation_reason`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: The gate's false-alarm rate per press (a trial's, for a combined-force model).
ALPHA = 0.01
#: A grating turned by 6 degrees reads its period 1/cos 6 = 0.55 % long along the line, far inside the 3 % a press
#: may move; the twin's straight presses read 0 +- 1.2 degrees (sd; at most 4.7 of 140 on the smooth pad), so
#: 6 flags what is turned and seldom what is straight.
ORIENTATION_TOLERANCE_DEG = 6.0
#: Descriptors compared on a log scale (the positive ones: ratios, levels); the rest as they are.
LOG_DESCRIPTORS = ("peak_over_noise", "ridges_over_noise", "ridges_over_band", "ridge_period_mm", "contrast_dn",
                   "mean_dn", "noise_dn", "noise_whiteness")
#: The smallest scale (standardised units) a descriptor is divided by: a descriptor constant over training does
#: not make every press infinitely far.
MIN_SCALE = 1e-3
#: A press with a descriptor beyond its training range by more than this many robust standard deviations (the
#: standardisation's units) is withheld whatever its p-value: a gross outlier is caught even where the training
#: presses are too few for the conformal test to reach alpha (fewer than 1 / alpha - 1: 99 at 1 %).
RANGE_MARGIN = 4.0
#: Covariance ridge (standardised units) before inverting: the detector stays defined for nearly collinear inputs.
RIDGE = 1e-3


@dataclass(frozen=True)
class ContactGate:
    """A fitted gate (module docstring): everything it needs to score is numbers, stored as JSON (model/gate_file.py)."""

    names: tuple[str, ...]
    center: np.ndarray  # (d,) standardisation
    scale: np.ndarray  # (d,)
    locations: np.ndarray  # (g, d): each held-out specimen's detector
    precisions: np.ndarray  # (g, d, d)
    calibration: np.ndarray  # (n,) held-out scores
    folds: np.ndarray  # (n,) which detector scored each
    low: np.ndarray  # (d,) training range, descriptors' own units
    high: np.ndarray
    alpha: float = ALPHA

    def standardised(self, values: np.ndarray) -> np.ndarray:
        """(n, d) descriptors -> standardised inputs (NaN where a descriptor could not be measured)."""
        return standardise(values, self.names, self.center, self.scale)

    def p_values(self, values: np.ndarray) -> np.ndarray:
        """The cross-conformal p-value of each row of (n, d) descriptors; a press with any unmeasured one gets the
        smallest p there is (it is like no training press)."""
        z = self.standardised(np.atleast_2d(values))
        scores = fold_scores(z, self.locations, self.precisions)  # (n, g)
        beaten = self.calibration[None, :] >= scores[:, self.folds]
        p = (1.0 + beaten.sum(axis=1)) / (self.calibration.size + 1.0)
        return np.where(np.isfinite(z).all(axis=1), p, 1.0 / (self.calibration.size + 1.0))

    def beyond_range(self, values: np.ndarray) -> np.ndarray:
        """Per row: a descriptor lies :data:`RANGE_MARGIN` beyond its training range (or could not be measured)."""
        z = self.standardised(np.atleast_2d(values))
        z_low = self.standardised(self.low[None, :])
        z_high = self.standardised(self.high[None, :])
        with np.errstate(invalid="ignore"):
            far = (z - z_high > RANGE_MARGIN) | (z_low - z > RANGE_MARGIN)
        return far.any(axis=1) | ~np.isfinite(z).all(axis=1)

    def withholds(self, values: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Per row of descriptors with its p-value: withheld (p at most alpha, or far beyond a training range)."""
        return (np.asarray(p) <= self.alpha) | self.beyond_range(values)

    @property
    def can_reach_alpha(self) -> bool:
        """Whether the conformal test can withhold at all: its smallest p is 1 / (n + 1)."""
        return 1.0 / (self.calibration.size + 1.0) <= self.alpha

    def reason(self, values: np.ndarray, p: float) -> str:
        """Why a withheld press is withheld, naming what is unlike the training presses."""
        return withheld_reason(self, np.asarray(values, dtype=float), p)


def standardise(values: np.ndarray, names, center: np.ndarray, scale: np.ndarray) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    logged = np.array([n in LOG_DESCRIPTORS for n in names])
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(logged, np.log(np.where(values > 0, values, np.nan)), values)
    return (z - center) / scale


def fold_scores(z: np.ndarray, locations: np.ndarray, precisions: np.ndarray) -> np.ndarray:
    """(n, g) squared Mahalanobis distances of each row under each fold's detector (NaN rows stay NaN)."""
    centred = z[:, None, :] - locations[None, :, :]
    return np.einsum("ngi,gij,ngj->ng", centred, precisions, centred)


def fit_gate(values: np.ndarray, names, specimens, *, seed: int, alpha: float = ALPHA) -> ContactGate:
    """The gate of training presses' descriptors ``values`` (n, d), calibrated over ``specimens`` (n,); a descriptor
    no training press could measure (a crop too small for it) is left out. ValueError when nothing is left or the
    presses are of fewer than two specimens."""
    values = np.asarray(values, dtype=np.float64)
    specimens = np.asarray(specimens).astype(str)
    measured = np.isfinite(values).all(axis=0) & (values.shape[0] > 0)  # a crop too small for one drops it
    if not measured.any():
        raise ValueError("no descriptor could be measured on the training presses (a crop too small)")
    names = [n for n, keep in zip(names, measured) if keep]
    values = values[:, measured]
    logged = np.array([n in LOG_DESCRIPTORS for n in names])
    with np.errstate(divide="ignore", invalid="ignore"):
        raw = np.where(logged, np.log(np.where(values > 0, values, np.nan)), values)
    keep = np.isfinite(raw).all(axis=1)
    center = np.median(raw[keep], axis=0)
    q75, q25 = np.percentile(raw[keep], [75, 25], axis=0)
    scale = np.maximum((q75 - q25) / 1.349, MIN_SCALE)
    z = (raw[keep] - center) / scale
    groups = specimens[keep]
    names_g = sorted(set(groups))
    if len(names_g) < 2:
        raise ValueError("the contact-image gate needs presses of at least two specimens")
    detectors = [_detector(z[groups != g], seed) for g in names_g]
    locations = np.stack([d[0] for d in detectors])
    precisions = np.stack([d[1] for d in detectors])
    folds = np.array([names_g.index(g) for g in groups])
    scores = fold_scores(z, locations, precisions)[np.arange(z.shape[0]), folds]
    return ContactGate(tuple(names), center, scale, locations, precisions, scores, folds,
                       np.min(values[keep], axis=0), np.max(values[keep], axis=0), float(alpha))


def _detector(z: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(location, precision) of a shrunk covariance (LedoitWolf) fitted to standardised presses (``seed`` is kept
    for a detector that draws)."""
    from sklearn.covariance import LedoitWolf

    fitted = LedoitWolf().fit(z)
    covariance = fitted.covariance_ + RIDGE * np.eye(z.shape[1])
    return fitted.location_, np.linalg.inv(covariance)


def trial_p_values(gate: ContactGate, values: np.ndarray, k: int) -> np.ndarray:
    """Per trial of ``k`` consecutive presses: the Bonferroni p, min(1, k x its smallest press p)."""
    p = gate.p_values(values)
    return np.minimum(1.0, k * p.reshape(-1, k).min(axis=1))


# --------------------------------------------------------------------------- the reasons, in the user's words

def _phrase(name: str, value: float, low: float, high: float, ridged: bool) -> str:
    """One descriptor outside its training range, as a user would say it."""
    span = f"training {_num(low)}-{_num(high)}"
    if not math.isfinite(value):
        return f"{name.replace('_', ' ')} could not be measured"
    if name == "peak_over_noise":
        lead = "no grating: " if value < low else ""
        return f"{lead}the band's peak stands {_num(value)}x above its noise (training presses {_num(low)}-{_num(high)}x)"
    if name == "ridges_over_noise":
        if ridged and value < low:
            return f"another pad: no ridges at 1 mm (their peak {_num(value)}x its noise, {span}x)"
        if not ridged and value > high:
            return f"another pad: ridges at 1 mm ({_num(value)}x above the noise, {span}x)"
        return f"ridge peak {_num(value)}x its noise ({span}x)"
    if name == "ridges_over_band":
        if not ridged and value > high:
            return f"another pad: a peak at 1 mm {_num(value)}x the band's own ({span}x)"
        if ridged and value < low:
            return f"another pad: the 1 mm ridges only {_num(value)}x the band's peak ({span}x)"
        return f"1 mm peak {_num(value)}x the band's ({span}x)"
    words = {"ridge_period_mm": "ridges {v} mm apart ({s} mm): magnified, or another pad or scale",
             "contrast_dn": "contrast {v} DN ({s})",
             "mean_dn": "brightness {v} DN ({s})",
             "noise_dn": "pixel noise {v} DN ({s}): magnified, resampled or another camera",
             "noise_whiteness": "smoothed pixel noise: whiteness {v} ({s}, 3 for a raw camera frame): magnified or "
                                "resampled",
             "coherence": "no lines along one direction: coherence {v} ({s})"}
    return words[name].format(v=_num(value), s=span)


def _num(value: float) -> str:
    return f"{value:.3g}"


def withheld_reason(gate: ContactGate, values: np.ndarray, p: float) -> str:
    """The descriptors furthest outside their training ranges (at most two), or the joint unlikeness."""
    ridged = "ridge_period_mm" in gate.names
    z = gate.standardised(values[None, :])[0]
    z_low = gate.standardised(gate.low[None, :])[0]
    z_high = gate.standardised(gate.high[None, :])[0]
    outside = np.where(np.isfinite(z), np.maximum(z - z_high, z_low - z), np.inf)
    order = [i for i in np.argsort(-outside) if outside[i] > 0][:2]
    test = f"p = {p:.2g} <= {gate.alpha:g}" if p <= gate.alpha else "far outside their range"
    head = f"not a contact image like the training presses ({test})"
    if not order:
        return f"{head}: every measure lies within its training range, but not together"
    return f"{head}: " + "; ".join(_phrase(gate.names[i], float(values[i]), float(gate.low[i]),
                                           float(gate.high[i]), ridged) for i in order)


def orientation_reason(angle_deg: float, tolerance_deg: float = ORIENTATION_TOLERANCE_DEG) -> str:
    """'' for a grating within the tolerance of straight; else why the press is flagged."""
    if not math.isfinite(angle_deg) or abs(angle_deg) <= tolerance_deg:
        return ""
    return (f"rotated: the grating's lines lean {angle_deg:+.1f} degrees from the image columns (tolerance "
            f"+-{tolerance_deg:g}); align the specimen with the camera")
