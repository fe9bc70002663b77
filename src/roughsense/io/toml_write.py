"""Writing study.toml: tables of scalars and lists, by tomli-w (the study writer and the calibration use it)."""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np


def dump_toml(tables: Mapping[str, Mapping[str, object]]) -> str:
    """study.toml's text from tables of scalars and lists, by tomli-w (NumPy scalars written as Python numbers).

    A dotted table name (``"pads.fingerprint"``) is a table inside a table, as it reads in a TOML header.
    """
    import tomli_w

    document: dict[str, dict] = {}
    for table, values in tables.items():
        node = document
        for part in table.split("."):
            node = node.setdefault(part, {})
        node.update({key: _plain(value) for key, value in values.items()})
    return tomli_w.dumps(document)


def _plain(value: object) -> object:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value
