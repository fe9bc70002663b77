"""Fit the simulated finger's free parameters to the paper's 13 rated specimens (not a test; docs/simulator.md).

Reads the paper's perceived roughness as shipped in roughsense.data.paper (the only place the finger model meets
the paper's results), fits the receptor depth, the saturation strain and the exponent
(scripts/finger_fitting.py), then the participants' spreads to the paper's SDs, runs the leave-one-specimen-out
check beside that of a two-parameter geometric law with no mechanics (log rating = b log(period/3) + c [circular]),
says which fitted parameters ended on their search bounds, and prints the constants to paste into
src/roughsense/sim/finger.py. docs/simulator.md quotes its numbers; tests/test_docs_figures.py recomputes them.

    PYTHONPATH=src .venv/bin/python scripts/fit_finger_to_paper.py
"""
from __future__ import annotations

import math

import numpy as np

from finger_fitting import (
    DEPTHS_MM,
    SATURATIONS,
    Validation,
    fit_readout,
    fit_spread,
    geometric_leave_one_out,
    leave_one_out,
    paired_p,
)
from roughsense.paper import PAPER_SPECIMENS, REFERENCE_SPECIMEN
from roughsense.sim import finger as finger_model
from roughsense.sim.panel import paper_perceived
from roughsense.sim.specimens import PRESETS


def main() -> None:
    paper = paper_perceived()
    names = [n for n in PAPER_SPECIMENS if n != REFERENCE_SPECIMEN]
    specimens = [PRESETS[n] for n in names]
    gmean = paper.loc[names, "perceived_gmean"].to_numpy(float)
    sd = paper.loc[names, "perceived_sd"].to_numpy(float)

    fit = fit_readout(specimens, gmean)
    finger = finger_model.Finger(receptor_depth_mm=fit.receptor_depth_mm, saturation_strain=fit.saturation_strain)
    log_ratios = [finger_model.log_ratio(s, finger=finger) for s in specimens]
    scale_sd, exponent_sd, session_sd = fit_spread(log_ratios, sd / gmean, fit.exponent)
    loso = leave_one_out(specimens, gmean)
    human_log_sd = float(np.median(np.sqrt(np.log1p((sd / gmean) ** 2))))

    print(f"in-sample RMS log error {fit.rms_log_error:.3f}")
    print(f"{'specimen':8s} {'paper':>6s} {'fit':>6s} {'loso':>6s} {'paper_sd':>8s} {'model_sd':>8s}")
    psych = finger_model.Psychophysics(fit.exponent, scale_sd, exponent_sd, session_sd)
    for name, g, s, lr, held in zip(names, gmean, sd, log_ratios, loso.predicted):
        typical = math.exp(fit.exponent * lr)
        print(f"{name:8s} {g:6.2f} {typical:6.2f} {held:6.2f} {s:8.2f} {typical * psych.log_sd_of_medians(lr):8.2f}")
    _compare(loso, geometric_leave_one_out(specimens, gmean), human_log_sd)
    print("\n# --- paste into src/roughsense/sim/finger.py ---")
    print(f"FITTED_RECEPTOR_DEPTH_MM = {fit.receptor_depth_mm!r}")
    print(f"FITTED_SATURATION_STRAIN = {fit.saturation_strain:.6g}")
    print(f"FITTED_EXPONENT = {fit.exponent:.6g}")
    print(f"FITTED_SCALE_SD = {scale_sd:.6g}")
    print(f"FITTED_EXPONENT_SD = {exponent_sd:.6g}")
    print(f"FITTED_SESSION_SD = {session_sd:.6g}")


def _on_bound(values: list[float], grid: tuple[float, ...]) -> str:
    ends = sum(v in (grid[0], grid[-1]) for v in values)
    return f"on a search bound ({grid[0]:g} or {grid[-1]:g}) in {ends} of {len(values)} folds"


def _compare(finger: Validation, law: Validation, human_log_sd: float) -> None:
    """The finger's leave-one-specimen-out beside the geometric law's: the mechanics must beat it to count."""
    print(f"LOSO on the paper's {len(finger.names)} rated gratings (median human log-SD {human_log_sd:.3f}):")
    for label, v in (("finger", finger), ("geometric law", law)):
        print(f"  {label:14s} Spearman rho = {v.spearman:.3f}, median |log(pred/obs)| = {v.median_abs_log_error:.3f}")
    print(f"  paired |log errors|, finger against law: Wilcoxon signed-rank p = {paired_p(finger, law):.2f}")
    print("  geometric law held out:", " ".join(f"{n} {p:.2f}" for n, p in zip(law.names, law.predicted)))
    print(f"finger folds: receptor depth {_on_bound([f.receptor_depth_mm for f in finger.folds], DEPTHS_MM)}; "
          f"saturation strain {_on_bound([f.saturation_strain for f in finger.folds], SATURATIONS)}")
    print("finger folds (depth, saturation, exponent):",
          sorted({(f.receptor_depth_mm, round(f.saturation_strain, 4), round(f.exponent, 3)) for f in finger.folds}))


if __name__ == "__main__":
    main()
