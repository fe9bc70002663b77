"""A fingerprint of the code a cell's numbers depend on: the twin and the analysis.

It is part of every cell's id, so results computed by another version are never mistaken for finished cells, and a
worker whose roughsense differs from the client's refuses the cell instead of mixing versions in one dataset.
"""
from __future__ import annotations

import hashlib
from functools import lru_cache
from importlib import resources

PACKAGES = ("roughsense", "roughsense.sim", "roughsense.explore", "roughsense.data.paper")
SKIP = {"report.py", "runner.py", "store.py", "summary.py", "__main__.py"}  # presentation and plumbing only


@lru_cache(maxsize=1)
def code_fingerprint() -> str:
    digest = hashlib.sha256()
    for package in PACKAGES:
        for item in sorted(resources.files(package).iterdir(), key=lambda p: p.name):
            if item.name.endswith((".py", ".csv")) and item.name not in SKIP:
                digest.update(f"{package}/{item.name}".encode())
                digest.update(item.read_bytes())
    return digest.hexdigest()[:12]
