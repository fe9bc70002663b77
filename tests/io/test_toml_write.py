"""io/toml_write.py: the study.toml text it writes reads back (by the standard library's tomllib) as the tables it
was given, NumPy scalars as plain numbers and a dotted table name as a table inside a table."""
from __future__ import annotations

import tomllib

import numpy as np

from roughsense.io.toml_write import dump_toml


def test_tables_read_back_as_written():
    tables = {"study": {"name": "batch 1", "synthetic": True},
              "sensor": {"px_per_mm": np.float64(34.9), "roi": [np.int64(0), 8, 400, np.int32(16)]},
              "pads.fingerprint": {"ridge_period_mm": 0.45}}
    document = tomllib.loads(dump_toml(tables))
    assert document == {"study": {"name": "batch 1", "synthetic": True},
                        "sensor": {"px_per_mm": 34.9, "roi": [0, 8, 400, 16]},
                        "pads": {"fingerprint": {"ridge_period_mm": 0.45}}}
    assert type(document["sensor"]["px_per_mm"]) is float and type(document["sensor"]["roi"][3]) is int
