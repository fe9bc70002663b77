"""The paper's own comparisons (Wilcoxon signed-rank on per-specimen RMSE) and whether its values describe a study.

Of the paper's PLS only: tests.csv has no model column, because these are the comparisons the paper made."""
from __future__ import annotations

from collections.abc import Sequence

import pandas as pd

from .. import paper
from ..model.registry import family
from .metrics import compare_conditions, signed_rank
from .results import CV_SCHEMES, StudyResults


def signed_rank_tests(analysis: StudyResults, conditions: Sequence[str]) -> pd.DataFrame:
    """Combined vs each single force per pad (Bonferroni x3), and smooth vs fingerprint on the combined condition.

    Of the paper's PLS only (tests.csv has no model column): these are the paper's own comparisons.
    """
    frames = []
    for cv in CV_SCHEMES:
        if not any(f.cv == cv and family(f.model).paper for f in analysis.fits):
            continue
        results = analysis.results(cv)
        paper_rows = results["model"].map(lambda name: family(name).paper).astype(bool)
        results = results[paper_rows].drop(columns="model")  # the paper's model, as the paper tested
        singles = [c for c in conditions if c != paper.COMBINED]
        for pad in analysis.pads:
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
        pads = analysis.pads
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


def paper_comparability(specimens: Sequence[str], pads: Sequence[str], conditions: Sequence[str],
                        reference_specimen: str) -> tuple[tuple[str, ...], str]:
    """The pads whose results may stand beside the paper's, and one note on why the others may not.

    The paper's numbers describe its 14 specimens, its two pads, its three forces and their combination,
    with R3 as the reference; beside any other design they would read as a comparison that is not one.
    """
    paper_specimens = list(paper.PAPER_SPECIMENS)
    problems = []
    if set(specimens) != set(paper_specimens):
        problems.append(f"its specimens ({', '.join(map(str, specimens))}) are not the paper's "
                        f"{len(paper_specimens)} ({', '.join(paper_specimens)})")
    if list(conditions) != list(paper.PAPER_CONDITIONS):
        problems.append(f"its conditions ({', '.join(conditions)}) are not the paper's {', '.join(paper.PAPER_CONDITIONS)}")
    if reference_specimen != paper.REFERENCE_SPECIMEN:
        problems.append(f"its reference is {reference_specimen}, the paper's {paper.REFERENCE_SPECIMEN}")
    if problems:
        return (), "The paper's values are not shown: " + "; ".join(problems) + "."
    matching = tuple(p for p in pads if p in paper.PAPER_PADS)
    others = [p for p in pads if p not in paper.PAPER_PADS]
    note = ""
    if others:
        note = (f"The paper's values are not shown for the {', '.join(others)} pad(s): the paper tested only the "
                f"{' and '.join(paper.PAPER_PADS)} pads.")
    return matching, note
