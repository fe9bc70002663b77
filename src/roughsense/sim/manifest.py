"""The manifest of simulated trials: the one definition of the table a simulated study's manifest.csv holds.

``simulate`` writes it into the folder; an explore cell keeps the same table in memory (with each image's condition
added as the study reader adds it), so a cell's study is the folder's study without the files.
"""
from __future__ import annotations

from collections.abc import Sequence

import pandas as pd


def trial_manifest(trials: Sequence, images: Sequence[str], contact_fractions: Sequence[float]) -> pd.DataFrame:
    """One row per trial (``simulate.Trial``) in order: its image, what was pressed on what, and how hard.

    ``images``: each trial's image path as the manifest names it; ``contact_fractions``: the share of the field in
    contact, as rendered. The scale's reading (``force_n``) and the true force are both kept, the latter to 1 uN.
    """
    return pd.DataFrame({
        "image": list(images),
        "specimen": [t.specimen.name for t in trials],
        "pad": [t.pad.name for t in trials],
        "force_n": [t.exposure.force_read_n for t in trials],
        "nominal_force_n": [t.nominal_force_n for t in trials],
        "repetition": [t.repetition for t in trials],
        "contact_fraction": [round(f, 6) for f in contact_fractions],
        "true_force_n": [round(t.exposure.force_true_n, 6) for t in trials],
    })
