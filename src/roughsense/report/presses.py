"""The report's "presses per surface" table and figure: renders analysis.presses, computes nothing of its own."""
from __future__ import annotations

import pandas as pd

from ..paper import COMBINED, press_meaning
from .figures import plt


def combined_press_words(conditions) -> str:
    """' In the combined condition, a press is one mount read at 1, 2 and 3 N.' where ``conditions`` hold the
    combined one (its presses are no single images), else ''."""
    return f" In the {COMBINED} condition, {press_meaning(COMBINED)}." if COMBINED in set(map(str, conditions)) else ""


def presses_table(presses: pd.DataFrame, presses_needed: dict) -> dict:
    """One row per pad and condition: the held-out error read from 1, 3, 5, 10 presses, and the presses needed
    (``presses_needed``: the analysis's, by (model, pad, condition))."""
    counts = sorted(presses["n_presses"].unique()) if len(presses) else []
    rows = []
    for (pad, condition), group in presses.groupby(["pad", "condition"], sort=False):
        by_count = group.set_index("n_presses")["rmse"]
        needed = presses_needed.get((str(group["model"].iloc[0]), str(pad), str(condition)))
        cells = [str(pad), str(condition), *[f"{by_count[k]:.3f}" if k in by_count else "—" for k in counts],
                 f"{group['null_rmse'].iloc[0]:.3f}", "none of these" if needed is None else str(needed)]
        rows.append([{"ours": cell, "paper": None} for cell in cells])
    return {
        "title": "Presses per surface: the peak law's error on a grating left out of training",
        "caption": ("Each held-out specimen scored as the mean of k of its presses (k drawn at random, 20 draws, "
                    "seeded), by the law fitted without it on every press of the others; mean over specimens of the "
                    "RMSE over draws, beside the training mean's. Presses needed: the fewest that gain at least half of "
                    "what the most presses gain over the training mean; roughsense predict says when a surface has "
                    "fewer." + combined_press_words(presses["condition"] if len(presses) else ())),
        "columns": ["Pad", "Condition", *[f"{k} press{'es' if k > 1 else ''}" for k in counts], "Training mean",
                    "Presses needed"],
        "rows": rows,
    }


def presses_figure(presses: pd.DataFrame):
    """Held-out RMSE against presses per surface, one panel per pad, a line per condition; dashed: training mean."""
    pads = list(dict.fromkeys(presses["pad"]))
    fig, axes = plt.subplots(1, len(pads), figsize=(4.2 * len(pads), 3.4), squeeze=False, sharey=True)
    for ax, pad in zip(axes[0], pads):
        mine = presses[presses["pad"] == pad]
        for condition, group in mine.groupby("condition", sort=False):
            ax.plot(group["n_presses"], group["rmse"], marker="o", label=str(condition))
        ax.axhline(float(mine["null_rmse"].iloc[0]), color="grey", linestyle="--", label="training mean")
        ax.set_title(f"{pad} pad")
        ax.set_xlabel("presses per surface")
        ax.set_xticks(sorted(mine["n_presses"].unique()))
    axes[0, 0].set_ylabel("held-out RMSE (mean per specimen)")
    axes[0, -1].legend(fontsize=8)
    fig.tight_layout()
    return fig
