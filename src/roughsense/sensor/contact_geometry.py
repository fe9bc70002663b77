"""The contact's geometry read from the whole contact band: land (contact) and groove (gap) widths in mm.

The names below are the measures' one home; the reading itself lands with issue 46's sensor work.
"""
from __future__ import annotations

#: Every contact measure a press yields, in order (units in the names).
CONTACT_MEASURES = ("land_mm", "groove_mm")
