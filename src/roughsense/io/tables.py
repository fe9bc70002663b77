"""The study folder's tables, by their old address: CSV reading is :mod:`.csv_read`'s, the TOML writer
:mod:`.toml_write`'s. The names below are re-exported for one release; import them from their homes.
"""
from __future__ import annotations

# re-exported for one release
from .csv_read import COLUMN_QUANTITY as COLUMN_QUANTITY
from .csv_read import MAX_CSV_BYTES as MAX_CSV_BYTES
from .csv_read import MAX_CSV_COLUMNS as MAX_CSV_COLUMNS
from .csv_read import NAME_COLUMNS as NAME_COLUMNS
from .csv_read import csv_line as csv_line
from .csv_read import missing_columns as missing_columns
from .csv_read import read_table as read_table
from .csv_read import read_text as read_text
from .csv_read import refuse_unknown as refuse_unknown
from .toml_write import dump_toml as dump_toml
