"""Cell tasks for the sweep tests: importable by Dask workers (they inherit the test process's sys.path)."""
from __future__ import annotations

from roughsense.explore.cell import run_cell


def fail_seed_one(cell):
    """Seed 1 raises on the worker (as a crashed task would); the others compute normally."""
    if cell.seed == 1:
        raise RuntimeError("boom on the worker\nsecond line")
    return run_cell(cell)
