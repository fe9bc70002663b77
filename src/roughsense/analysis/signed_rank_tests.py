"""The paper's own comparisons (Wilcoxon signed-rank on per-specimen RMSE).

Of the paper's PLS only: tests.csv has no model column, because these are the comparisons the paper made."""
from __future__ import annotations

from collections.abc import Sequence

import pandas as pd

from .. import paper
from ..model.registry import family
from .metrics import compare_conditions, signed_rank
from .results import CV_SCHEMES, CrossValidation


def signed_rank_tests(cross_validation: CrossValidation, conditions: Sequence[str]) -> pd.DataFrame:
    """Combined vs each single force per pad (Bonferroni x3), and smooth vs fingerprint on the combined condition.

    Of the paper's PLS only (tests.csv has no model column): these are the paper's own comparisons.
    """
    frames = []
    for cv in CV_SCHEMES:
        if not any(f.cv == cv and family(f.model).paper for f in cross_validation.fits):
            continue
        results = cross_validation.results(cv)
        paper_rows = results["model"].map(lambda name: family(name).paper).astype(bool)
        results = results[paper_rows].drop(columns="model")  # the paper's model, as the paper tested
        singles = [c for c in conditions if c != paper.COMBINED]
        for pad in cross_validation.pads:
            if paper.COMBINED not in conditions or not singles:
                break
            by_condition = {
                c: results[(results.pad == pad) & (results.condition == c)].set_index("specimen")["rmse"]
                for c in conditions
            }
            table = compare_conditions(by_condition, paper.COMBINED, singles, bonferroni=len(singles))
            table["comparison"] = f"{pad}: " + table["comparison"].astype(str)
            table["cv"] = cv
            frames.append(table)
        pads = cross_validation.pads
        if len(pads) == 2:
            first, second = sorted(pads, key=lambda p: (p != paper.SMOOTH_PAD, p))
            rows = []
            # The paper compares the pads on the combined condition only (Section 4); so do we.
            for condition in [c for c in conditions if c == paper.COMBINED] or list(conditions[-1:]):
                a = results[(results.pad == first) & (results.condition == condition)].set_index("specimen")["rmse"]
                b = results[(results.pad == second) & (results.condition == condition)].set_index("specimen")["rmse"]
                common = a.index.intersection(b.index)
                test = signed_rank(a.loc[common].to_numpy(), b.loc[common].to_numpy())
                rows.append({"comparison": f"{condition}: {first} vs {second}", "statistic": test.statistic,
                             "p": test.p, "p_adjusted": test.p, "cv": cv, "n": test.n, "method": test.method})
            frames.append(pd.DataFrame(rows))
    if not frames:
        return pd.DataFrame(columns=["comparison", "statistic", "p", "p_adjusted", "cv"])
    tests = pd.concat(frames, ignore_index=True)
    front = ["comparison", "statistic", "p", "p_adjusted", "cv"]
    return tests[front + [c for c in tests.columns if c not in front]]
