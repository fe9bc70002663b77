"""The model families, chosen by name wherever a model is chosen (``--model``, model files, the ``model`` column):
the one list that holds each family from ``study`` and ``fit`` to its model file and ``predict``.

``pls`` is the paper's PLS1 (SIMPLS) on the spectral amplitudes: the paper's reproduction and design sweeps use it
(:data:`PAPER_MODEL`). ``peak-law`` is the peak power law, built to predict surfaces the model never saw; it passes
its controls for unseen surfaces where PLS fails them, so ``fit`` writes it unless told otherwise
(:data:`DEFAULT_MODEL`). ``groove`` reads the contact's geometry (land and groove widths, per press) rather than the
spectra: a power law of the terms that earn their place under nested leave-one-specimen-out, groove width first.

A :class:`Family` is what the report, the tables and the command line know without NumPy (``--help`` lists the
names): its name, title, colours, the ``fit`` options only it takes, and the dotted path of its numerics, a
:class:`roughsense.model.family.FamilyEngine` imported when first asked for (:func:`engine`). The engine owns the
rest of the family's life: its cross-validation for the study and for ``fit``, its training record, its model-file
section (written, checked, loaded), its jackknife+ folds and its domain flags. The generic modules (modelfile,
jackknife_file, schema, training_file, analysis/training, cli/fit) ask the engine and never name a family, so a
new family is one package and one :func:`register` call (a test registers one and removes it with
:func:`unregister`).
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass

from ..errors import ConfigError

PLS = "pls"
PEAK_LAW = "peak-law"
GROOVE = "groove"
#: What ``roughsense fit`` writes unless --model says otherwise, by what the training design can tell apart
#: (docs/groove.md, "The default"): where the study's rectangles are all one land/groove geometry (the paper's: half
#: land), the period stands in for the groove and the peak law did best; where they vary land against groove at a
#: period, the groove model passed its controls and the held-out schemes best (the twin's paper+grooves, seeds 0-2).
DEFAULT_MODEL = PEAK_LAW
GEOMETRY_MODEL = GROOVE
#: The paper's model: its reproduction and the design sweeps' default family.
PAPER_MODEL = PLS


@dataclass(frozen=True)
class FitOption:
    """An option of ``roughsense fit`` that only the families declaring it take: its flag, ``train_model``'s keyword
    for it, and what it does (the refusal of it with another family says so)."""

    flag: str
    keyword: str
    purpose: str


@dataclass(frozen=True)
class Family:
    """What the report, the tables and the command line know of a family without importing its numerics.

    ``paper``: the paper's model (its claims, signed-rank tests and published values are of it). ``engine_path``:
    ``"package.module:Class"`` of its :class:`~roughsense.model.family.FamilyEngine`. ``options``: the ``fit``
    options it takes beyond every family's. ``description``: what it predicts from, in a user's words: the one text
    ``fit --model``'s help and the report's method section give (:func:`model_help`).
    """

    name: str
    title: str
    marker: str
    colour: str
    paper: bool
    engine_path: str
    options: tuple[FitOption, ...] = ()
    description: str = ""

    def engine(self):
        """A fresh engine (stateless), its module imported on first use."""
        module, _, attribute = self.engine_path.partition(":")
        return getattr(importlib.import_module(module), attribute)()


_CHOOSES = "chooses PLS components"
_FAMILIES: list[Family] = [
    Family(PLS, "PLS (the paper's model)", "o", "#2f5d8a", paper=True,
           engine_path="roughsense.model.pls.family:PLSFamily",
           options=(FitOption("--rule", "rule", _CHOOSES), FitOption("--max-components", "max_components", _CHOOSES)),
           description="the paper's PLS1 (SIMPLS) on the spectrum's amplitudes, to reproduce the paper"),
    Family(PEAK_LAW, "peak law", "s", "#c0392b", paper=False,
           engine_path="roughsense.model.peak_law.family:PeakLawFamily",
           description="a power law of where the contact spectrum peaks (the period), times one of the contact's "
                       "shape (its second harmonic against the fundamental) where the training surfaces show more "
                       "than one shape; the peak's height is no term (it only bounds the domain)"),
    Family(GROOVE, "groove model", "D", "#2e8b57", paper=False, engine_path="roughsense.model.groove.family:GrooveFamily",
           description="a power law of the contact's geometry read from the image: groove (gap) width first, then "
                       "land width, the groove's change with force and the contact fraction, each term kept only "
                       "where it lowers the error on specimens held out (nested); a surface's presses read together"),
]

#: Every built-in family's name, the paper's first (:func:`names` follows the registry at run time).
MODEL_FAMILIES = tuple(f.name for f in _FAMILIES)


def register(family: Family) -> None:
    """Add a family after the others (a name already registered is refused)."""
    if family.name in names():
        raise ConfigError(f"a model family called {family.name!r} is already registered")
    _FAMILIES.append(family)


def unregister(name: str) -> None:
    """Remove the family called ``name`` (a test's, once it is done)."""
    _FAMILIES[:] = [f for f in _FAMILIES if f.name != name]


def registry() -> tuple[Family, ...]:
    """Every family, in the order of every table (the paper's first)."""
    return tuple(_FAMILIES)


def names() -> tuple[str, ...]:
    """Every registered family's name, in table order."""
    return tuple(f.name for f in _FAMILIES)


def family(name: str | Family) -> Family:
    """The family called ``name`` (as :func:`check_model_name` accepts it)."""
    if isinstance(name, Family):
        return name
    checked = check_model_name(name)
    return next(f for f in _FAMILIES if f.name == checked)


def paper_family() -> Family:
    """The paper's model: its claims, signed-rank tests and published values are of it, and sweeps fit it."""
    return next(f for f in _FAMILIES if f.paper)


def default_model(varies_geometry: bool = False) -> str:
    """What ``roughsense fit`` writes unless told otherwise: :data:`GEOMETRY_MODEL` where the training study's
    rectangles vary land against groove (``varies_geometry``), else :data:`DEFAULT_MODEL`."""
    return GEOMETRY_MODEL if varies_geometry else DEFAULT_MODEL


#: How fit's help marks the two defaults.
_DEFAULT_WORDS = {DEFAULT_MODEL: " (the default where every rectangle has one land/groove geometry, as the paper's)",
                  GEOMETRY_MODEL: " (the default where the rectangles vary land against groove at a period)"}


def model_help() -> str:
    """``fit --model``'s help: every family's name and :attr:`Family.description`, the defaults marked."""
    def one(f: Family) -> str:
        default = _DEFAULT_WORDS.get(f.name, "")
        return f"{f.name}{default}: {f.description}" if f.description else f"{f.name}{default}"

    return "Model family. " + "; ".join(one(f) for f in _FAMILIES) + "."


def check_model_name(name: object, *, option: str = "--model") -> str:
    """The family's name, case-insensitive; anything else is one line naming the choices."""
    text = str(name).strip().lower() if isinstance(name, str) else None
    known = names()
    if text not in known:
        raise ConfigError(f"{option} must be one of {', '.join(known)}, got {name!r}")
    return text


def engines() -> tuple:
    """Every family's numerics (:class:`roughsense.model.family.FamilyEngine`), in the registry's order."""
    return tuple(f.engine() for f in _FAMILIES)


def engine(name: str | Family):
    """The numerics of the family called ``name`` (or of the :class:`Family` given)."""
    return family(name).engine()


def engine_of_kind(kind: object):
    """The engine whose model-file section is of ``kind``, or None (a kind no registered family writes)."""
    return next((e for e in engines() if e.kind == kind), None)


def kinds() -> tuple[str, ...]:
    """Every registered family's model-file section kind, in the registry's order."""
    return tuple(e.kind for e in engines())
