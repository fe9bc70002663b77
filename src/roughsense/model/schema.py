"""One schema for the model file: every section's JSON Schema and cross-field facts, checked on loading.

Why JSON Schema (``jsonschema``, Draft 2020-12). A model file is JSON that users send each other, and its checksum
is unkeyed: the field checks are what refuse an edited file. Written by hand they were ``isinstance`` chains spread
over five modules, and a section nobody chained (``training.presses``, ``training.unseen``) was not checked at all.
JSON Schema states a section's fields, types, bounds, known values and unknown keys as data, in the vocabulary every
JSON tool reads, and ``jsonschema`` (the reference implementation, maintained for over a decade) checks all of it;
pydantic would give classes to keep beside the dataclasses that already hold the loaded model, and its messages
name fields in its own words. What a schema cannot say -- facts that relate fields (the folds bracket the model,
the condition agrees with the features, a verdict agrees with its numbers) -- is a function beside the schema.

A section is a place in the document (a dotted path, ``training.presses``) with its schema and, optionally, its
check; each is stated in the module of the code that writes and reads it, and :func:`sections` lists them. To plug
a new section in, state ``SCHEMA`` (and a ``check(value, document, fail)`` if fields relate) in its module and add
one line to :func:`sections`; a new top-level key also goes into ``modelfile.OPTIONAL_TOP_KEYS``. A
section absent from a file is skipped (its parent's schema says whether it is required). A family's ``model``
section is checked first by its own module's code (whose messages say why a bound is where it is, and which derives
bounds from other fields: shapes from the component count, a law's finite exponent over its feature box), then by
its schema, which states the whole section in one place (``after_family``).

Every refusal is one line naming the file and the field, with what was expected and what was found::

    M.json: training.presses.rmse_by_presses['1']: expected a number from 0 to 1e+06, got 'abc'

A schema node's ``description`` is what the message says is expected (else it is built from ``type``, ``enum`` and
the bounds). A count is a JSON integer: ``3.0`` is not one (Draft 2020-12 would take it; here it is refused, as
every reader of roughsense refuses a float where a count belongs). Duplicate keys are refused while parsing
(:func:`loads_unique`): JSON readers disagree on which of two values counts, and the checksum covered only one.
"""
from __future__ import annotations

import json
import re
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from .._util.checks import short_repr, shown
from ..errors import ModelFileError

#: What a section's check is called with: its value, the whole document, and ``fail(field, message)``, which
#: raises the one-line refusal (``field`` relative to the section, e.g. ``"needed"`` or ``"pct_var[0]"``; "" for
#: the section itself).
Check = Callable[[object, dict, Callable[[str, str], None]], None]


@dataclass(frozen=True)
class Section:
    """One section of a model file: its JSON Schema and, when its fields relate, its check. ``after_family``: checked
    once the model's family has loaded its section with its own messages (the schema then states the rest)."""

    schema: dict
    check: Check | None = None
    after_family: bool = False


def sections() -> dict[str, Section]:
    """Every checked section, by its dotted place in the document, parents before children (each module states
    its own; see the module docstring for adding one)."""
    from . import gate_file, interval, jackknife_file, modelfile, training_file
    from .registry import engines

    families = engines()
    return {
        "model": Section(_by_kind_schema(families), _by_kind({f.kind: f.check_section for f in families}),
                         after_family=True),
        "features": Section(modelfile.FEATURES_SCHEMA),
        "training": Section(training_file.training_schema(families), training_file.check),
        "training.presses": Section(training_file.PRESSES_SCHEMA, training_file.check_presses),
        "training.unseen": Section(training_file.UNSEEN_SCHEMA, training_file.check_unseen),
        "training.interval": Section(interval.SCHEMA, interval.check_record),
        "training.jackknife_plus": Section(jackknife_file.jackknife_schema(families)),
        f"training.{gate_file.KEY}": Section(gate_file.SCHEMA, gate_file.check),
    }


def check_document(document: dict, path: Path | None, *, after_family: bool = False) -> None:
    """Every section of :func:`sections` present in ``document`` (those checked before the family's own loading,
    or with ``after_family`` those after it): its schema, then its check."""
    for where, section in sections().items():
        value, found = _at(document, where)
        if not found or section.after_family != after_family:
            continue
        refusal = first_refusal(value, section.schema, where)
        if refusal is not None:
            raise ModelFileError(refusal, path=path)
        if section.check is not None:
            section.check(value, document, failing(where, path))


def _by_kind_schema(families) -> dict:
    """The ``model`` section's schema: the registered family's of its ``kind`` (the last family's for any other
    kind, which loading has refused before this is checked)."""
    node = families[-1].section_schema
    for family in reversed(families[:-1]):
        node = {"if": {"properties": {"kind": {"const": family.kind}}}, "then": family.section_schema, "else": node}
    return node


def _by_kind(checks: dict[str, Check]) -> Check:
    """The check of a section whose ``kind`` says which family's it is."""
    def check(value, document: dict, fail) -> None:
        if value.get("kind") in checks:
            checks[value["kind"]](value, document, fail)

    return check


def failing(where: str, path: Path | None) -> Callable[[str, str], None]:
    def fail(field: str, message: str) -> None:
        raise ModelFileError(f"{where}.{field}: {message}" if field else f"{where}: {message}", path=path)

    return fail


def _at(document: dict, where: str) -> tuple[object, bool]:
    value: object = document
    for key in where.split("."):
        if not isinstance(value, dict) or key not in value:
            return None, False
        value = value[key]
    return value, True


# --------------------------------------------------------------------------- validation and its messages


@cache
def _validator_class():
    from jsonschema import Draft202012Validator, validators

    def whole(_checker, value) -> bool:  # a JSON integer, never 3.0 (nor true)
        return type(value) is int

    checker = Draft202012Validator.TYPE_CHECKER.redefine("integer", whole)
    return validators.extend(Draft202012Validator, type_checker=checker)


@cache
def _validator(schema_json: str):
    return _validator_class()(json.loads(schema_json))


def first_refusal(value: object, schema: dict, where: str) -> str | None:
    """The one-line refusal of ``value`` (found at ``where``) by ``schema``, or None when it conforms."""
    validator = _validator(json.dumps(schema, sort_keys=True))
    errors = sorted(validator.iter_errors(value), key=lambda e: (len(e.absolute_path), _rank(e.validator),
                                                                  [str(p) for p in e.absolute_path]))
    return None if not errors else _message(errors[0], where)


def _rank(validator: str) -> int:
    """Among errors at one place, the one that says most: an unknown or missing field, then a type."""
    return {"required": 0, "additionalProperties": 1, "propertyNames": 1, "type": 2}.get(validator, 3)


def _message(error, where: str) -> str:
    place = join(where, *error.absolute_path)
    if error.validator == "required":
        missing = next(k for k in error.validator_value if k not in error.instance)
        wanted = error.schema.get("properties", {}).get(missing, {})
        return f"{join(place, missing)}: missing" + (f" (expected {describe(wanted)})" if wanted else "")
    if error.validator == "additionalProperties":
        known = set(error.schema.get("properties", {}))
        pattern = "|".join(error.schema.get("patternProperties", {}))
        extra = sorted(k for k in error.instance if k not in known and not (pattern and re.search(pattern, k)))
        return f"{join(place, extra[0])}: unknown field" if extra else f"{place}: has an unknown field"
    if error.validator == "propertyNames":
        name = error.instance if isinstance(error.instance, str) else next(iter(error.instance), "")
        return f"{place}: has the field {short_repr(name)}; expected {describe(error.validator_value)}"
    if error.validator in ("minItems", "maxItems") and isinstance(error.instance, list):
        return f"{place}: expected {describe(error.schema)}, got {len(error.instance)} item(s)"
    return f"{place}: expected {describe(error.schema)}, got {_got(error.instance)}"


def _got(value: object) -> str:
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, (dict, list)):
        text = json.dumps(value)
        return f"{'an object' if isinstance(value, dict) else 'an array'} {text if len(text) <= 40 else text[:37] + '...'}"
    return shown(value) if isinstance(value, (int, float)) else short_repr(value)


_TYPES = {"number": "a number", "integer": "a whole number", "string": "a string", "boolean": "true or false",
          "null": "null", "array": "an array", "object": "an object"}


def describe(schema: dict) -> str:
    """What a schema node accepts, in a message's words (its ``description`` when it has one)."""
    if "description" in schema:
        return schema["description"]
    if "const" in schema:
        return json.dumps(schema["const"])
    if "enum" in schema:
        return "one of " + ", ".join(json.dumps(v) for v in schema["enum"])
    types = schema.get("type", [])
    types = [types] if isinstance(types, str) else list(types)
    words = " or ".join(_TYPES.get(t, t) for t in types if t != "null") or "a value"
    low, high = schema.get("minimum", schema.get("exclusiveMinimum")), schema.get("maximum")
    if low is not None and high is not None:
        words += f" from {shown(low)} to {shown(high)}"
    elif low is not None:
        words += f" {'above' if 'exclusiveMinimum' in schema else 'at least'} {shown(low)}"
    elif high is not None:
        words += f" at most {shown(high)}"
    if "items" in schema and isinstance(schema["items"], dict) and "array" in types:
        length = schema.get("minItems") if schema.get("minItems") == schema.get("maxItems") else None
        words = (f"an array of {length} " if length is not None else "an array of ") + describe(schema["items"])
    return words + (" or null" if "null" in types else "")


def join(where: str, *keys) -> str:
    """A field's place as a message names it: ``training.presses.rmse_by_presses['1']``, ``folds.intercept[3]``."""
    text = where
    for key in keys:
        if isinstance(key, int):
            text += f"[{key}]"
        elif isinstance(key, str) and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", key):
            text += f".{key}" if text else key
        else:
            text += f"[{short_repr(str(key), 30)}]"
    return text


# --------------------------------------------------------------------------- parsing


class RepeatedKeyError(ValueError):
    """A JSON object holding a key twice; the message names the field."""


class _Pairs(dict):
    """A JSON object that held a key twice (the first such key in ``repeated``)."""

    repeated: str


def loads_unique(text: str) -> object:
    """``json.loads``, refusing an object that holds a key twice with :class:`RepeatedKeyError` naming the field."""
    repeats = []

    def pairs_hook(pairs: list) -> dict:
        found = dict(pairs)
        if len(found) == len(pairs):
            return found
        seen: set[str] = set()
        marked = _Pairs(found)
        marked.repeated = next(k for k, _ in pairs if k in seen or seen.add(k))
        repeats.append(marked)
        return marked

    document = json.loads(text, object_pairs_hook=pairs_hook)
    if not repeats:
        return document
    queue: deque[tuple[object, tuple]] = deque([(document, ())])
    while queue:  # where the first repeated key is, in document order, found without recursion
        node, keys = queue.popleft()
        if isinstance(node, _Pairs):
            raise RepeatedKeyError(f"{join('', *keys, node.repeated)}: the key appears twice in one object (JSON readers "
                             "disagree on which value counts)")
        children = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
        queue.extend((child, (*keys, key)) for key, child in children)
    return document


# --------------------------------------------------------------------------- shared schema fragments


def number(low: float | None = None, high: float | None = None, *, null: bool = False, **more) -> dict:
    """A JSON number within [low, high] (or null)."""
    node: dict = {"type": ["number", "null"] if null else "number", **more}
    if low is not None:
        node["minimum"] = low
    if high is not None:
        node["maximum"] = high
    return node


def integer(low: int | None = None, high: int | None = None, **more) -> dict:
    """A JSON integer (never 3.0) within [low, high]."""
    return number(low, high, **more) | {"type": more.get("type", "integer")}


def strict(properties: dict, required=(), **more) -> dict:
    """An object of exactly these properties (the ``required`` ones present), and no other."""
    return {"type": "object", "properties": properties, "required": list(required), "additionalProperties": False,
            **more}
