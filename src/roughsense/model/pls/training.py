"""PLS trained for a model file (``roughsense fit --model pls``): its component count chosen by cross-validation under
the scheme the user chose, by ``--rule`` (the paper's §3.3: the curve's minimum by default), the model fitted on
every trial at that count, and its applicability domain (limits cross-validated over specimens, the peak readout of
the same trials); and what ``fit`` prints of it, the CV curve with the counts marked.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from ... import defaults
from ..._util.checks import POSITIVE_INT, Options, check
from ..._util.text import counted
from ...errors import ConfigError, InputError
from ..family import Trained, TrainingSet
from ..schema import integer

#: How ``--rule`` chooses the count: the curve's minimum, or the fewest components within one SE of it.
RULES = ("min", "1se")
#: The fields PLS adds to a model file's training record (model/training_file.py), as JSON Schema.
TRAINING_SCHEMA = {
    "rule": {"enum": list(RULES)},
    "max_components": integer(1, None),
    "best_n_components": integer(0, None),
    "one_se_n_components": integer(0, None),
    "n_components": integer(1, None),
}


def check_pls_options(options) -> None:
    """``--rule`` and ``--max-components``, refused in one line before any image is read."""
    if options.get("rule") is not None:
        check(options["rule"], Options(RULES), name="--rule", must="min or 1se")
    if options.get("max_components") is not None:
        check(options["max_components"], POSITIVE_INT, name="--max-components", must="at least 1")


def cross_validate(X: np.ndarray, y: np.ndarray, specimens: np.ndarray, scheme: str | int, *, seed: int,
                   max_components: int | None, what: str):
    """PLS CV over 0..max components; the default maximum shrinks to what the folds support, a user's does not.

    How many components the data support is pls_cv's to say (rank, smallest training fold): a maximum the user
    did not give is capped there, and data that support none are refused in words that name the problem.
    """
    from .cv import pls_cv
    from .simpls import PLSConfigError

    groups = specimens if scheme == "loso" else None
    # The seed, not a Generator: a capped retry must shuffle the K folds exactly as the first try did.
    try:
        return pls_cv(
            X, y, max_components=defaults.MAX_COMPONENTS if max_components is None else max_components,
            cv=None if scheme == "loso" else scheme, groups=groups, random_state=seed, cap=max_components is None,
        )
    except PLSConfigError as exc:
        if exc.supported is not None and exc.supported < 1:
            cv_text = scheme if isinstance(scheme, str) else str(scheme)
            raise ConfigError(f"too few samples ({len(y)}) for {cv_text} cross-validation of {what}") from None
        raise


def train_pls(data: TrainingSet) -> Trained:
    """The count chosen by the rule under the user's CV, the model fitted on every trial with its domain
    (``domain_``, which its model-file section keeps), and the record's CV fields."""
    from ..readout_domain import ReadoutSettings
    from .applicability import fit_domain
    from .simpls import SIMPLS

    rule = data.options.get("rule") or "min"
    result = cross_validate(data.X, data.y, data.specimens, data.scheme, seed=data.seed,
                            max_components=data.options.get("max_components"), what=data.what)
    _refuse_no_better_than_mean(result, data.what, data.source)
    chosen = result.best_n_components if rule == "min" else result.one_se_n_components
    record = {
        "rule": rule,
        "max_components": int(result.max_components),
        "cv_rmse": [float(v) for v in result.rmse],
        "cv_rmse_se": [float(v) for v in result.rmse_se],
        "best_n_components": int(result.best_n_components),
        "one_se_n_components": int(result.one_se_n_components),
        "n_components": int(chosen),
    }
    fitted = SIMPLS(n_components=chosen).fit(data.X, data.y)
    settings = data.settings  # the peak readout of the same trials, beside the spectrum's shape
    readout = ReadoutSettings(settings.freq_per_mm, settings.n_blocks, settings.pad_ridge_period_mm)
    fitted.domain_ = fit_domain(fitted, data.X, data.y, np.asarray(data.specimens).astype(str), law=readout)
    return Trained(fitted, result, int(chosen), record)


def _refuse_no_better_than_mean(result, what: str, source) -> None:
    """Refuse a PLS model whose every component count cross-validates worse than the training mean (0 components):
    its spectra carry nothing the CV can find about the ratings, and a model file would predict noise."""
    best = int(np.argmin(result.rmse[1:])) + 1
    if not result.rmse[best] < result.rmse[0]:
        raise InputError(f"no PLS component count beats the training mean for {what} in cross-validation (CV RMSE "
                         f"{result.rmse[best]:.4g} at {best} vs {result.rmse[0]:.4g} with none); the spectra do not "
                         "predict the ratings, so no model is written", path=source)


def curve_table(result, chosen: int) -> pd.DataFrame:
    """The CV curve as printed by ``fit``: RMSE and its SE per component count, the minimum, 1-SE and chosen marked."""
    marks = []
    for k in range(result.rmse.size):
        tags = []
        if k == result.best_n_components:
            tags.append("min")
        if k == result.one_se_n_components:
            tags.append("1-SE")
        if k == chosen:
            tags.append("chosen")
        marks.append(", ".join(tags))
    return pd.DataFrame(
        {"components": range(result.rmse.size), "rmse": result.rmse, "rmse_se": result.rmse_se, "note": marks}
    )


def pls_report(trained) -> tuple[pd.DataFrame, list[str]]:
    """What ``fit`` prints: the CV curve, then the chosen count."""
    result, chosen = trained.cv, trained.n_components
    return curve_table(result, chosen), [
        f"chosen: {counted(chosen, 'component')} (CV RMSE {result.rmse[chosen]:.5f}; "
        f"min at {result.best_n_components}, one-SE rule {result.one_se_n_components})"]


def check_pls_training(training: dict, model: dict, fail) -> None:
    """A PLS record's component counts: the model's, within the curve it chose them from."""
    if "n_components" in training and training["n_components"] != model.get("n_components"):
        fail("n_components", f"is {training['n_components']}, but the model has {model.get('n_components')}")
    tried = len(training["cv_rmse"]) - 1 if "cv_rmse" in training else None
    if tried is not None and "max_components" in training and tried != training["max_components"]:
        fail("cv_rmse", f"has {tried + 1} values, but max_components {training['max_components']} gives "
                        f"{training['max_components'] + 1}")
    for name in ("best_n_components", "one_se_n_components", "n_components"):
        if tried is not None and training.get(name, 0) > tried:
            fail(name, f"is {training[name]}, beyond the {tried} components cross-validated")
