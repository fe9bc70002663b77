"""The paper's published numbers, shipped with the package so reports can sit beside them offline.

Values are transcribed from Yanwari & Okamoto, Sensors 25:2598 (2025): Tables 1-6 (as CSV in
``data/paper``), the component counts chosen by LOO (Section 4) and the signed-rank tests quoted in the text.
"""
from __future__ import annotations

from functools import lru_cache
from importlib import resources

import pandas as pd

PAPER_CITATION = "Yanwari & Okamoto, Sensors 25:2598 (2025)"
REFERENCE_SPECIMEN = "R3"

#: Number of PLS components chosen by leave-one-out CV (Section 4).
PAPER_BEST_N_COMPONENTS = {
    ("fingerprint", "1N"): 8,
    ("fingerprint", "2N"): 8,
    ("fingerprint", "3N"): 10,
    ("fingerprint", "combined"): 12,
    ("smooth", "1N"): 11,
    ("smooth", "2N"): 10,
    ("smooth", "3N"): 12,
    ("smooth", "combined"): 15,
}

#: LOO RMSE of the fingerprint combined model around its minimum (Figure 8 caption).
PAPER_FIG8_RMSE = {11: 0.22330, 12: 0.22326, 13: 0.22328}

#: Signed-rank tests quoted in Section 4: comparison -> (W, p as reported, Bonferroni factor, how p was reported).
PAPER_TESTS = {
    "fingerprint: combined vs 1N": (6.0, 4.8e-3, 3, "="),
    "fingerprint: combined vs 2N": (14.0, 7.2e-4, 3, "="),
    "fingerprint: combined vs 3N": (0.0, 1.2e-4, 3, "="),
    "combined: smooth vs fingerprint": (6.0, 0.0017, 1, "<"),
}


def _read(name: str) -> pd.DataFrame:
    with resources.files("roughsense.data.paper").joinpath(name).open("r", encoding="utf-8") as handle:
        return pd.read_csv(handle, dtype={"specimen": str, "pad": str, "condition": str, "shape": str})


@lru_cache(maxsize=None)
def _paper_results() -> pd.DataFrame:
    return _read("paper_results.csv")


@lru_cache(maxsize=None)
def _perceived() -> pd.DataFrame:
    return _read("perceived_roughness.csv")


def paper_results() -> pd.DataFrame:
    """Tables 1-6 in long form: pad, specimen, condition, pred_mean, pred_sd, ovl, rmse."""
    return _paper_results().copy()


def perceived_roughness() -> pd.DataFrame:
    """Perceived roughness per specimen: specimen, shape, wavelength_mm, perceived_gmean, perceived_sd."""
    return _perceived().copy()
