"""The model families, chosen by name wherever a model is chosen (``--model``, model files, the ``model`` column).

``pls`` is the paper's PLS1 (SIMPLS) on the spectral amplitudes: the paper's reproduction and design sweeps use it
(:data:`PAPER_MODEL`). ``peak-law`` is :class:`roughsense.model.peak_law.law.PeakPowerLaw`, built to predict surfaces the
model never saw; it passes its controls for unseen surfaces where PLS fails them, so ``fit`` writes it unless told
otherwise (:data:`DEFAULT_MODEL`). This module imports
nothing heavy, so the command line can list and check the names without loading scikit-learn: a family's numerics
(:class:`roughsense.model.family.FamilyEngine`) are imported by :func:`engines` when first asked for. A third family
is one engine module, one :class:`Family` line here and one import line in :func:`engines`.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import ConfigError

PLS = "pls"
PEAK_LAW = "peak-law"
#: What ``roughsense fit`` writes unless --model says otherwise: the family that answers "how rough does a surface I
#: never trained on feel?" (the study's "surfaces never seen" section judges it).
DEFAULT_MODEL = PEAK_LAW
#: The paper's model: its reproduction and the design sweeps' default family.
PAPER_MODEL = PLS


@dataclass(frozen=True)
class Family:
    """What the report, the tables and the model files know of a family without importing its numerics.

    ``paper``: the paper's model (its claims, signed-rank tests and published values are of it). ``chooses_components``:
    it picks a count by cross-validation (``--rule``, ``--max-components`` apply). ``kind``: its model-file section.
    """

    name: str
    title: str
    marker: str
    colour: str
    paper: bool
    chooses_components: bool
    kind: str


_FAMILIES = (
    Family(PLS, "PLS (the paper's model)", "o", "#2f5d8a", paper=True, chooses_components=True, kind="pls1-simpls"),
    Family(PEAK_LAW, "peak law", "s", "#c0392b", paper=False, chooses_components=False, kind="peak-power-law"),
)


#: Every family's name, the paper's first (the registry's order at import; :func:`names` follows it at run time).
MODEL_FAMILIES = tuple(f.name for f in _FAMILIES)


def registry() -> tuple[Family, ...]:
    """Every family, in the order of every table (the paper's first)."""
    return _FAMILIES


def names() -> tuple[str, ...]:
    """Every registered family's name, in table order."""
    return tuple(f.name for f in registry())


def family(name: str | Family) -> Family:
    """The family called ``name`` (as :func:`check_model_name` accepts it)."""
    if isinstance(name, Family):
        return name
    checked = check_model_name(name)
    return next(f for f in registry() if f.name == checked)


def paper_family() -> Family:
    """The paper's model: its claims, signed-rank tests and published values are of it, and sweeps fit it."""
    return next(f for f in registry() if f.paper)


def default_family() -> Family:
    """What ``roughsense fit`` writes unless told otherwise (:data:`DEFAULT_MODEL`)."""
    return family(DEFAULT_MODEL)


def check_model_name(name: object, *, option: str = "--model") -> str:
    """The family's name, case-insensitive; anything else is one line naming the choices."""
    text = str(name).strip().lower() if isinstance(name, str) else None
    known = names()
    if text not in known:
        raise ConfigError(f"{option} must be one of {', '.join(known)}, got {name!r}")
    return text
