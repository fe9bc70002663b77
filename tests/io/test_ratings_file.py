"""io/ratings_file.py: the ratings readers (CSV and a filled-in Markdown sheet) refuse an ambiguous table."""
from __future__ import annotations

import pytest

from roughsense.errors import InputError


def test_a_markdown_sheet_with_a_column_named_twice_is_refused(tmp_path):
    """28.7 for the other ratings reader: a filled-in Markdown sheet kept the last of two rating columns."""
    from roughsense.io.ratings_file import read_ratings

    path = tmp_path / "sheet.md"
    path.write_text("| participant | session | specimen | rating | rating |\n|---|---|---|---|---|\n| P1 | 1 | R2 | 5 | 0.5 |\n")
    with pytest.raises(InputError, match="table column 'rating' appears twice in the header") as info:
        read_ratings(path)
    assert info.value.row == 1
