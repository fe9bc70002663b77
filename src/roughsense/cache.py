"""Where roughsense keeps what it can recompute: the built-in simulated study and extracted features.

The cache is ``$ROUGHSENSE_CACHE_DIR``, else ``$XDG_CACHE_HOME/roughsense``, else ``~/.cache/roughsense``.
Entries are keyed by content, so a stale entry is never reused: features are keyed by the manifest,
the sensor settings and every image's size and modification time.
"""
from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from . import atomic


def cache_dir() -> Path:
    explicit = os.environ.get("ROUGHSENSE_CACHE_DIR")
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "roughsense"


def features_key(study, feature_definition: dict) -> str:
    digest = hashlib.sha256()
    digest.update(str(Path(study.root).resolve()).encode())
    digest.update(json.dumps(feature_definition, sort_keys=True, default=str).encode())
    digest.update((Path(study.root) / "manifest.csv").read_bytes())
    for path in study.image_paths:
        stat = path.stat()
        digest.update(f"{path.name}:{stat.st_size}:{stat.st_mtime_ns}".encode())
    return digest.hexdigest()[:24]


def cached_frame(key: str, compute: Callable[[], pd.DataFrame], *, kind: str = "features") -> tuple[pd.DataFrame, bool]:
    """Return (frame, was_cached). Stored as pickle-free CSV with text columns kept as text."""
    path = cache_dir() / kind / f"{key}.csv"
    if path.is_file():
        try:
            frame = pd.read_csv(path, dtype={"image": str, "specimen": str, "pad": str, "condition": str},
                                keep_default_na=False, na_values=[""])
            return frame, True
        except (OSError, ValueError, pd.errors.ParserError):
            pass  # a damaged cache entry is simply recomputed
    frame = compute()
    try:
        atomic.write_csv(path, frame, float_format="%.17g")
    except Exception:  # the cache is an optimisation: never fail the run because it cannot be written
        pass
    return frame, False
