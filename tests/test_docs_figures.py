"""Speed figures quoted in the README stay within what BENCHMARKS.md records (the README rounds down, never up)."""
from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _benchmark_row(start: str) -> str:
    rows = [line for line in (REPO / "BENCHMARKS.md").read_text(encoding="utf-8").splitlines() if line.startswith(start)]
    assert len(rows) == 1, f"BENCHMARKS.md has no single row starting {start!r}"
    return rows[0].split("|")[2]  # the result column


def _ratios(text: str) -> list[float]:
    return [float(x) for x in re.findall(r"(\d+(?:\.\d+)?)x", text)]


def test_the_readme_pls_speedups_are_at_most_the_recorded_ones():
    readme = " ".join((REPO / "README.md").read_text(encoding="utf-8").split())
    quoted = re.search(r"exact LOO over 1\.\.20 components is more than (\d+)× faster than scikit-learn and "
                       r"more than (\d+)× faster than ikpls", readme)
    assert quoted, "the README no longer quotes the LOO speed-ups; update this test with it"
    sklearn = _ratios(_benchmark_row("| LOO 1..20 components, n=140, p=135: >= 200x scikit-learn"))
    ikpls = _ratios(_benchmark_row("| same: >= 10x ikpls fast CV"))
    assert sklearn and ikpls
    assert float(quoted.group(1)) <= min(sklearn)
    assert float(quoted.group(2)) <= min(ikpls)
