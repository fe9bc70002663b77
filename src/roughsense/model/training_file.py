"""The ``training`` section of a model file: what the model was fitted on and how it was judged, as
analysis/training.py records it, stated as JSON Schema (model/schema.py) and checked against the rest of the file.

Every key is optional (a model saved from Python may record as little as ``{}``), but one that is there has its
known type and bounds, and no other key is accepted: the fields every family writes are stated here, those a family
adds by the family (its ``training_schema``, model/registry.py). The facts that relate fields are checked beside
the schema:

- ``condition`` and ``pad`` agree with the features: a condition's spectra are its force's (``combined``: all
  three, side by side), and the pad's ``pad_ridge_period_mm`` is the one the model leaves out of its peak search
  (a fingerprint model relabelled as smooth keeps its ridge exclusion, so the two would disagree);
- the family's own facts (its ``check_training``; PLS: ``n_components`` is the model's, the CV curve has one value
  per count tried);
- ``presses.needed`` is one of the press counts it was measured at, and beats the training mean there;
- ``unseen``'s verdict agrees with its numbers: ``passes_controls`` is true exactly when ``failure`` is empty,
  and a permutation p-value is one a count of shufflings gives.

Bounds: an RMSE is of ratings, so within a rating's bound (``io.numbers.BOUNDS``); counts of presses within a
manifest's repetitions; shufflings within ``defaults.MAX_PERMUTATIONS``.
"""
from __future__ import annotations

import math

from .. import defaults
from .._util.checks import MAX_SEED
from ..io.numbers import BOUNDS
from ..paper import COMBINED, FORCE_CONDITIONS, PAPER_CONDITIONS
from .registry import engine_of_kind
from .schema import integer, number, strict

_RATING = BOUNDS["rating"]
_RIDGE = BOUNDS["ridge_period_mm"]
_PRESSES = BOUNDS["repetition"].high
_RMSE = number(0.0, _RATING.high)
_STRINGS = {"type": "array", "items": {"type": "string"}}

PRESSES_SCHEMA = strict({
    "needed": integer(1, _PRESSES, type=["integer", "null"], description="a count of presses or null"),
    "null_rmse": _RMSE,
    "rmse_by_presses": {"type": "object", "minProperties": 1, "additionalProperties": _RMSE,
                        "propertyNames": {"pattern": r"^[1-9][0-9]{0,3}$", "description": "a count of presses"}},
}, required=("needed", "null_rmse", "rmse_by_presses"))

#: What ``failure`` starts with when the model was judged and failed, and when it could not be judged.
FAILS = "this model FAILS its controls"
UNJUDGED = "this model could not be judged"
UNSEEN_SCHEMA = strict({
    "cv": {"const": "loso (nested)"},
    "rmse": number(0.0, _RATING.high, null=True),
    "null_rmse": number(0.0, _RATING.high, null=True),
    "pooled_rmse": number(0.0, _RATING.high, null=True),
    "null_pooled_rmse": number(0.0, _RATING.high, null=True),
    "permutation_p": number(0.0, 1.0, null=True, exclusiveMinimum=0.0),
    "n_permutations": integer(0, defaults.MAX_PERMUTATIONS),
    "passes_controls": {"type": ["boolean", "null"], "description": "true, false or null"},
    "failure": {"type": "string"},
}, required=("cv", "passes_controls", "failure"))

SCHEMA = strict({
    "study": {"type": "string"},
    "study_path": {"type": "string"},
    "pad": {"type": "string", "minLength": 1},
    "condition": {"enum": list(PAPER_CONDITIONS)},
    "n_samples": integer(1, None),
    "specimens": {**_STRINGS, "minItems": 1, "uniqueItems": True},
    "reference_specimen": {"type": ["string", "null"]},
    "cv": {"type": "string", "pattern": r"^(loo|loso|[1-9][0-9]*-fold)$",
           "description": "loo, loso or K-fold"},
    "seed": integer(0, MAX_SEED),
    "study_roi": {"oneOf": [{"enum": ["center", "auto"]},
                            {"type": "array", "items": integer(0, None), "minItems": 4, "maxItems": 4}],
                  "description": "center, auto or [x, y, w, h]"},
    "target_range": {"type": "array", "items": number(_RATING.low, _RATING.high), "minItems": 2, "maxItems": 2},
    "pad_ridge_period_mm": number(_RIDGE.low, _RIDGE.high, null=True),
    "cv_rmse": {"type": "array", "items": _RMSE, "minItems": 1},
    "cv_rmse_se": {"type": "array", "items": _RMSE, "minItems": 1},
    "scale_check": {"type": "string"},
    "unseen": {"type": "object"},
    "interval": {"type": "object"},
    "jackknife_plus": {"type": "object"},
    "contact_gate": {"type": "object"},
    "presses": {"type": "object"},
})


def training_schema(families) -> dict:
    """:data:`SCHEMA` with the fields each registered family adds to the record (its ``training_schema``)."""
    fields = dict(SCHEMA["properties"])
    for family in families:
        fields.update(family.training_schema)
    return {**SCHEMA, "properties": fields}


def check(training: dict, document: dict, fail) -> None:
    """The training record against the features and the model (see the module docstring)."""
    conditions = document.get("features", {}).get("conditions")
    condition = training.get("condition")
    if condition is not None and conditions is not None:
        expected = list(FORCE_CONDITIONS) if condition == COMBINED else [condition]
        if conditions != expected:
            fail("condition", f"is {condition!r}, but the features are spectra at {', '.join(conditions)}")
    target = training.get("target_range")
    if target is not None and target[0] > target[1]:
        fail("target_range", f"must be [smallest, largest] of the ratings trained on, got {target}")
    model = document.get("model", {})
    family = engine_of_kind(model.get("kind"))
    if family is not None and family.ridge_period_place is not None and "pad_ridge_period_mm" in training:
        _check_pad(training, model, family.ridge_period_place, fail)
    if family is not None:
        family.check_training(training, model, fail)
    for name in ("cv_rmse_se",):
        if name in training and "cv_rmse" in training and len(training[name]) != len(training["cv_rmse"]):
            fail(name, f"has {len(training[name])} values, but cv_rmse has {len(training['cv_rmse'])}")


def _check_pad(training: dict, model: dict, place: str, fail) -> None:
    """The pad's ridge period as the study stated it is the one the model leaves out of its peak search (held at
    ``place`` in its section, as its family says)."""
    stated, held = training["pad_ridge_period_mm"], model
    for key in place.split("."):
        held = held.get(key, "absent") if isinstance(held, dict) else "absent"
    if held != "absent" and held != stated:
        fail("pad_ridge_period_mm", f"is {stated} for pad {training.get('pad', '')!r}, but the model's peak search "
                                    f"leaves out the ridges of model.{place} = {held}")


def check_presses(presses: dict, document: dict, fail) -> None:
    """``needed`` is a count the curve was measured at, and there it beats the training mean."""
    needed, curve = presses["needed"], presses["rmse_by_presses"]
    if needed is None:
        return
    if str(needed) not in curve:
        fail("needed", f"is {needed}, not one of the press counts measured ({', '.join(curve)})")
    if not curve[str(needed)] < presses["null_rmse"]:
        fail("needed", f"is {needed}, but {needed} presses do not beat the training mean "
                       f"({curve[str(needed)]:.4g} vs {presses['null_rmse']:.4g})")


def check_unseen(unseen: dict, document: dict, fail) -> None:
    """The verdict agrees with its numbers and its words."""
    passes, failure = unseen["passes_controls"], unseen["failure"]
    if passes is True and failure:
        fail("failure", "must be empty when passes_controls is true")
    if passes is False and not failure.startswith(FAILS):
        fail("failure", f"must say why the model fails its controls (\"{FAILS} ...\") when passes_controls is false")
    if passes is None and not failure.startswith(UNJUDGED):
        fail("failure", f"must say why the model was not judged (\"{UNJUDGED} ...\") when passes_controls is null")
    pooled, null_pooled = unseen.get("pooled_rmse"), unseen.get("null_pooled_rmse")
    if passes is True and not (isinstance(pooled, float | int) and isinstance(null_pooled, float | int)
                               and pooled < null_pooled):
        fail("passes_controls", f"is true, but the pooled RMSE {pooled} does not beat the training mean's "
                                f"{null_pooled}")
    p, count = unseen.get("permutation_p"), unseen.get("n_permutations")
    if p is not None and count is not None:
        shufflings_as_good = p * (count + 1) - 1  # p = (1 + k) / (1 + n)
        if count == 0 or not math.isclose(shufflings_as_good, round(shufflings_as_good), abs_tol=1e-6):
            fail("permutation_p", f"is {p}, which no count of {count} shufflings gives ((1 + k) / {count + 1})")
