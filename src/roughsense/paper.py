"""The paper's published numbers, shipped with the package so reports can sit beside them offline.

Values are transcribed from Yanwari & Okamoto, Sensors 25:2598 (2025): Tables 1-6 (as CSV in
``data/paper``), the component counts chosen by LOO (Section 4) and the signed-rank tests quoted in the text.
"""
from __future__ import annotations

from functools import cache
from importlib import resources
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd  # imported when a table is read: the CLI's --help reads only the constants

PAPER_CITATION = "Yanwari & Okamoto, Sensors 25:2598 (2025)"
#: The reference every rating is relative to: fixed at 1.0 by definition, never rated (Section 3.1).
REFERENCE_SPECIMEN = "R3"
#: The paper's gratings: rectangular (R) and circular (C), wavelength 2-5 mm in 0.5 mm steps.
PAPER_WAVELENGTHS_MM = (2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0)
PAPER_SPECIMENS = tuple(f"{shape}{w:g}" for shape in "RC" for w in PAPER_WAVELENGTHS_MM)
#: The pads the paper tested (Tables 1-3 and 4-6): one with fingerprint-like ridges, one smooth.
FINGERPRINT_PAD = "fingerprint"
SMOOTH_PAD = "smooth"
PAPER_PADS = (FINGERPRINT_PAD, SMOOTH_PAD)
#: The protocol (Section 3): each specimen pressed at 1, 2 and 3 N, 10 repetitions; 10 participants rate each
#: specimen in 3 sessions.
PAPER_FORCES_N = (1.0, 2.0, 3.0)
PAPER_REPETITIONS = 10
PAPER_PARTICIPANTS = 10
PAPER_SESSIONS = 3
#: The models' conditions: one per force, and "combined" (the three spectra of a trial side by side).
FORCE_CONDITIONS = ("1N", "2N", "3N")
COMBINED = "combined"
PAPER_CONDITIONS = (*FORCE_CONDITIONS, COMBINED)
#: What one press is in the combined condition, said wherever presses are counted: a trial's three images, taken
#: with the specimen mounted once and pressed at each force in turn (not three presses).
COMBINED_PRESS = ("a press is one mount read at " + ", ".join(c[:-1] for c in FORCE_CONDITIONS[:-1])
                  + f" and {FORCE_CONDITIONS[-1][:-1]} N")


def press_meaning(condition: str) -> str:
    """What one press is in ``condition``: :data:`COMBINED_PRESS` in the combined condition, '' in a single force's
    (a press is one image there)."""
    return COMBINED_PRESS if str(condition).lower() == COMBINED else ""

#: Number of PLS components chosen by leave-one-out CV (Section 4).
PAPER_BEST_N_COMPONENTS = {
    (FINGERPRINT_PAD, "1N"): 8,
    (FINGERPRINT_PAD, "2N"): 8,
    (FINGERPRINT_PAD, "3N"): 10,
    (FINGERPRINT_PAD, COMBINED): 12,
    (SMOOTH_PAD, "1N"): 11,
    (SMOOTH_PAD, "2N"): 10,
    (SMOOTH_PAD, "3N"): 12,
    (SMOOTH_PAD, COMBINED): 15,
}

#: LOO RMSE of the fingerprint combined model around its minimum (Figure 8 caption).
PAPER_FIG8_RMSE = {11: 0.22330, 12: 0.22326, 13: 0.22328}

#: Signed-rank tests quoted in Section 4: comparison -> (W, p as printed, whether the printed p is the
#: Bonferroni-adjusted one, "=" or "<" as printed). Recomputing them from the rounded Table 3/6 values
#: (docs/perception.md) shows 4.8e-3 and 7.2e-4 are adjusted (x3) while 1.2e-4 is the unadjusted p.
PAPER_TESTS = {
    "fingerprint: combined vs 1N": (6.0, 4.8e-3, True, "="),
    "fingerprint: combined vs 2N": (14.0, 7.2e-4, True, "="),
    "fingerprint: combined vs 3N": (0.0, 1.2e-4, False, "="),
    "combined: smooth vs fingerprint": (6.0, 0.0017, False, "<"),
}

#: Summary rows as printed in Tables 2, 3, 5 and 6 (mean, SD over specimens):
#: (pad, metric, condition, group) -> (mean, sd). Tables 3 and 6 print only the overall row. Table 5's
#: rectangular and overall rows do not follow from its own per-specimen values (docs/perception.md),
#: which is why the report shows these printed values rather than recomputing them.
PAPER_SUMMARIES = {
    **{(FINGERPRINT_PAD, "ovl", c, g): v for g, values in {
        "rectangular": [(0.52, 0.20), (0.54, 0.20), (0.53, 0.20), (0.55, 0.13)],
        "circular": [(0.58, 0.12), (0.58, 0.11), (0.58, 0.11), (0.57, 0.14)],
        "all": [(0.56, 0.15), (0.56, 0.15), (0.56, 0.16), (0.56, 0.13)],
    }.items() for c, v in zip(PAPER_CONDITIONS, values)},
    **{(FINGERPRINT_PAD, "rmse", c, "all"): v for c, v in
       zip(PAPER_CONDITIONS, [(0.26, 0.11), (0.25, 0.09), (0.25, 0.10), (0.21, 0.07)])},
    **{(SMOOTH_PAD, "ovl", c, g): v for g, values in {
        "rectangular": [(0.65, 0.16), (0.63, 0.18), (0.60, 0.19), (0.64, 0.20)],
        "circular": [(0.53, 0.16), (0.55, 0.15), (0.49, 0.11), (0.50, 0.17)],
        "all": [(0.59, 0.17), (0.59, 0.16), (0.55, 0.16), (0.57, 0.19)],
    }.items() for c, v in zip(PAPER_CONDITIONS, values)},
    **{(SMOOTH_PAD, "rmse", c, "all"): v for c, v in
       zip(PAPER_CONDITIONS, [(0.16, 0.05), (0.18, 0.05), (0.16, 0.05), (0.13, 0.03)])},
}


def _read(name: str) -> pd.DataFrame:
    import pandas as pd

    with resources.files("roughsense.data.paper").joinpath(name).open("r", encoding="utf-8") as handle:
        return pd.read_csv(handle, dtype={"specimen": str, "pad": str, "condition": str, "shape": str})


@cache
def _paper_results() -> pd.DataFrame:
    return _read("paper_results.csv")


@cache
def _perceived() -> pd.DataFrame:
    return _read("perceived_roughness.csv")


def paper_results() -> pd.DataFrame:
    """Tables 1-6 in long form: pad, specimen, condition, pred_mean, pred_sd, ovl, rmse."""
    return _paper_results().copy()


def perceived_roughness() -> pd.DataFrame:
    """Perceived roughness per specimen: specimen, shape, wavelength_mm, perceived_gmean, perceived_sd."""
    return _perceived().copy()
