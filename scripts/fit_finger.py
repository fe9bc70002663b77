"""Fit the simulated finger's free parameters to the paper's 13 rated specimens (not a test; docs/simulator.md).

Reads the paper's perceived roughness as shipped in roughsense.data.paper (the only place the finger model meets
the paper's results), fits the receptor depth, the saturation strain and the exponent
(roughsense.sim.finger_fit), then the participants' spreads to the paper's SDs, runs the leave-one-specimen-out
check and prints the constants to paste into src/roughsense/sim/finger.py.

    PYTHONPATH=src .venv/bin/python scripts/fit_finger.py
"""
from __future__ import annotations

import math

import numpy as np

from roughsense.paper import PAPER_SPECIMENS
from roughsense.sim import finger as finger_model
from roughsense.sim.finger_fit import fit_readout, fit_spread, leave_one_out
from roughsense.sim.panel import paper_perceived
from roughsense.sim.specimens import PRESETS


def main() -> None:
    paper = paper_perceived()
    names = [n for n in PAPER_SPECIMENS if n != finger_model.REFERENCE]
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
    print(f"LOSO: median |log(pred/obs)| = {loso.median_abs_log_error:.3f} (median human log-SD {human_log_sd:.3f}), "
          f"Spearman rho = {loso.spearman:.3f}")
    print("folds (depth, saturation, exponent):",
          sorted({(f.receptor_depth_mm, round(f.saturation_strain, 4), round(f.exponent, 3)) for f in loso.folds}))
    print("\n# --- paste into src/roughsense/sim/finger.py ---")
    print(f"FITTED_RECEPTOR_DEPTH_MM = {fit.receptor_depth_mm!r}")
    print(f"FITTED_SATURATION_STRAIN = {fit.saturation_strain:.6g}")
    print(f"FITTED_EXPONENT = {fit.exponent:.6g}")
    print(f"FITTED_SCALE_SD = {scale_sd:.6g}")
    print(f"FITTED_EXPONENT_SD = {exponent_sd:.6g}")
    print(f"FITTED_SESSION_SD = {session_sd:.6g}")


if __name__ == "__main__":
    main()
