"""Predictive distributions of percepts: a model of how widely people's ratings spread around a mean.

The paper's OVL compares the spread of the sensor's repeated predictions with the spread of people's
ratings. A perfect, noiseless sensor (every repetition predicting the people's geometric mean exactly)
would put a point mass at the right place and score OVL near 0: the metric rewards a noisy sensor whose
noise happens to be as wide as the disagreement between people. A sensor predicts *what people perceive*;
the spread between people is a property of people, not of the image.

So the sensor's point predictions are turned into a distribution of percepts with a :class:`SpreadModel`:
each prediction x becomes N(x, s(x)^2), where s is the spread of ratings around a perceived value, learnt
from the ratings of *other* specimens only. Magnitude estimates scatter in proportion to the magnitude
(Weber-like; ratings are log-normal with one spread in log units), so the default is s(x) = k x, with k
the pooled coefficient of variation of the training specimens' ratings. A specimen's predictive
distribution is the mixture of its repetitions' distributions, summarised like the paper's by a normal of
the same mean and variance, which keeps the sensor's own scatter in it:
var = E[s(X)^2] + Var(X) over the repetitions X. ``ovl_predictive`` is the OVL of that distribution with
the people's, N(gmean, sd).
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator

from ..errors import ConfigError, InputError
from .metrics import overlap

KINDS = ("weber", "constant")


class SpreadModel(BaseEstimator):
    """The spread (SD) of people's ratings as a function of the perceived value: s(m) = intercept_ + slope_ m.

    ``kind="weber"``: s = k m, k = sqrt(mean((sd / gmean)^2)) -- the pooled coefficient of variation, i.e.
    the pooled SD of log ratings (log-normal spread, equal panels). ``kind="constant"``: s = sqrt(mean(sd^2)),
    the pooled SD, whatever the mean (the spread the paper's sensor shows). Specimens without a spread
    (the reference, whose SD is NaN) are ignored. scikit-learn conventions: parameters in ``__init__``,
    fitted values with a trailing underscore, ``fit`` returns self.

    Parameters
    ----------
    kind : {"weber", "constant"}
        The spread grows in proportion to the perceived value, or stays the same.

    Examples
    --------
    >>> import roughsense as rs
    >>> spread = rs.SpreadModel().fit([0.5, 1.0, 1.5, 2.0], [0.1, 0.2, 0.3, 0.4])  # SD = 20 % of the mean
    >>> round(spread.slope_, 3), round(spread.predict_sd(1.4), 3)
    (0.2, 0.28)
    >>> round(spread.predictive_sd(1.4, 0.1), 3)  # people's spread plus the sensor's own scatter
    0.298
    """

    def __init__(self, kind: str = "weber"):
        self.kind = kind

    def fit(self, gmean, sd) -> SpreadModel:
        """Learn the spread from each specimen's perceived value and the SD of its ratings.

        Parameters
        ----------
        gmean : array-like
            (n_specimens,) perceived roughness (geometric mean of the ratings).
        sd : array-like
            (n_specimens,) the SD of the ratings; NaN for a specimen without one (the reference).

        Returns
        -------
        SpreadModel
            This model, fitted: ``intercept_``, ``slope_``, ``n_specimens_``.
        """
        if self.kind not in KINDS:
            raise ConfigError(f"SpreadModel: kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        gmean = np.asarray(gmean, dtype=float).ravel()
        sd = np.asarray(sd, dtype=float).ravel()
        if gmean.shape != sd.shape:
            raise InputError(f"SpreadModel.fit: gmean has {gmean.size} values and sd {sd.size}")
        keep = np.isfinite(gmean) & np.isfinite(sd)
        if np.any(sd[keep] < 0) or (self.kind == "weber" and np.any(gmean[keep] <= 0)):
            raise InputError("SpreadModel.fit: SDs must be >= 0 and (for kind='weber') means > 0")
        if not keep.any():
            raise InputError("SpreadModel.fit: no specimen with both a mean and an SD to learn the spread from")
        if self.kind == "weber":
            self.intercept_, self.slope_ = 0.0, float(np.sqrt(np.mean((sd[keep] / gmean[keep]) ** 2)))
        else:
            self.intercept_, self.slope_ = float(np.sqrt(np.mean(sd[keep] ** 2))), 0.0
        self.n_specimens_ = int(keep.sum())
        return self

    def predict_sd(self, mean):
        """Spread of people's ratings of a surface whose perceived value is ``mean`` (never negative).

        Parameters
        ----------
        mean : float or array-like
            Perceived values.

        Returns
        -------
        float or numpy.ndarray
            The SD of the ratings, shaped like ``mean``.
        """
        self._check_fitted()
        mean = np.asarray(mean, dtype=float)
        result = self.intercept_ + self.slope_ * np.maximum(mean, 0.0)
        return float(result) if result.ndim == 0 else result

    def predictive_sd(self, mean, sd):
        """SD of the mixture of N(x, s(x)^2) over predictions x with mean ``mean`` and population SD ``sd``.

        E[s(X)^2] = (a + b m)^2 + b^2 sd^2 for s(x) = a + b x, so the variance is that plus sd^2: the
        people's spread around each prediction and the sensor's own scatter between repetitions.

        Parameters
        ----------
        mean : float or array-like
            The mean of a surface's predictions.
        sd : float or array-like
            Their SD over repetitions.

        Returns
        -------
        float or numpy.ndarray
            The SD of what a person would say of the surface, as the sensor predicts it.
        """
        self._check_fitted()
        mean = np.asarray(mean, dtype=float)
        sd = np.asarray(sd, dtype=float)
        a, b = self.intercept_, self.slope_
        result = np.sqrt((a + b * mean) ** 2 + (b * b + 1.0) * sd**2)
        return float(result) if result.ndim == 0 else result

    def _check_fitted(self) -> None:
        if not hasattr(self, "slope_"):
            from sklearn.exceptions import NotFittedError

            raise NotFittedError("SpreadModel is not fitted; call fit(gmean, sd) first")


def predictive_ovl(table: pd.DataFrame, perceived: pd.DataFrame, *, kind: str = "weber") -> pd.DataFrame:
    """``ovl_predictive`` and ``predictive_sd`` per row of a per-specimen table, spread learnt without it.

    ``table`` has specimen, gmean, sd, pred_mean, pred_sd (population SD of the repetitions);
    ``perceived`` has specimen, gmean, sd for every specimen whose ratings may train the spread model.
    For each specimen the model is fitted to the *other* specimens' (gmean, sd) -- leave one specimen out --
    so nothing about its own ratings enters its predictive distribution. The reference (no SD) gets NaN OVL.
    """
    people = perceived.set_index("specimen")
    ovl, psd = [], []
    for _, row in table.iterrows():
        others = people.drop(index=row["specimen"], errors="ignore")
        if not (others["gmean"].notna() & others["sd"].notna()).any():  # nobody else to learn the spread from
            psd.append(float("nan"))
            ovl.append(float("nan"))
            continue
        model = SpreadModel(kind).fit(others["gmean"], others["sd"])
        width = model.predictive_sd(row["pred_mean"], row["pred_sd"])
        psd.append(width)
        ovl.append(overlap(row["gmean"], row["sd"], row["pred_mean"], width))
    return pd.DataFrame({"predictive_sd": psd, "ovl_predictive": ovl}, index=table.index)


def paper_predictive(kind: str = "weber") -> pd.DataFrame:
    """The predictive OVL of the paper's own published predictions (Tables 1 and 4), leave one specimen out.

    Rows: pad, condition, specimen, gmean, sd, pred_mean, pred_sd, ovl (the paper's), predictive_sd,
    ovl_predictive. The spread model sees only the paper's perceived values of the other specimens.
    """
    from .. import paper

    people = paper.perceived_roughness().rename(columns={"perceived_gmean": "gmean", "perceived_sd": "sd"})
    results = paper.paper_results().merge(people[["specimen", "gmean", "sd"]], on="specimen", how="left")
    frames = []
    for _, group in results.groupby(["pad", "condition"], sort=False):
        extra = predictive_ovl(group, people, kind=kind)
        frames.append(pd.concat([group, extra], axis=1))
    columns = ["pad", "condition", "specimen", "gmean", "sd", "pred_mean", "pred_sd", "ovl", "predictive_sd",
               "ovl_predictive"]
    return pd.concat(frames, ignore_index=True)[columns]
