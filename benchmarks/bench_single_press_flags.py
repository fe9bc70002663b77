"""Why presses of the fingerprint pad read alone are withheld or flagged (issue 43's in-distribution goal), per cause.

For every press at the model's force of other sessions of the twin, read alone with the fingerprint pad's default
model (``fit --study builtin --pad fingerprint --condition 2N``), this says which test fired, and whether the press's
peak was read where its grating is (within 10 % of its period: "read right") or elsewhere ("misread"), with the
press's |log error| against the panel's roughness of its specimen. A flag on a misread press is honest (its
prediction is wrong); only a flag on a press read right is a false alarm a better test could remove.

Causes, in the order predict applies them: the contact-image gate (withheld); the band test on the press
(``sensor/band.py``: its strongest structure outside the band >= DOMINANCE x the band's own), split by where that
structure is (the ridges' odd harmonics just outside their fixed exclusion window: a mount's magnification moves the
n-th harmonic n times as far; a coarse shading hump; other); the peak law's own domain flags.

Run: .venv/bin/python benchmarks/bench_single_press_flags.py --studies S1 S2 ... (study folders; ``simulate --seed K``)
"""
from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

import roughsense as rs

CONDITION = "2N"
#: A press's peak is read right when it lies within this log distance of its grating's period (10 %).
RIGHT_LOG = 0.1


def press_table(model: str, folder: Path) -> pd.DataFrame:
    """One row per fingerprint press of ``folder`` at CONDITION: the band reading, the law's reading, the verdicts."""
    from roughsense.analysis.dataset import perceived_roughness
    from roughsense.model.modelfile import load_model
    from roughsense.model.reading import model_ridge_period_mm
    from roughsense.model.scoring import image_readings
    from roughsense.sensor.band import DOMINANCE, band_reading

    loaded = load_model(model)
    study = rs.read_study(folder)
    rows = study.manifest[(study.manifest["pad"] == "fingerprint") & (study.manifest["condition"] == CONDITION)]
    paths = [str(folder / image) for image in rows["image"]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = rs.predict(model, paths)
    X, lines, spectrum = image_readings(loaded, paths)
    freq = spectrum.freq_per_mm_
    readings = [band_reading(line, float(spectrum.px_per_mm), float(freq[0]), float(freq[-1]),
                             ridge_period_mm=model_ridge_period_mm(loaded)) for line in lines]
    panel = perceived_roughness(study).set_index("specimen")["gmean"]
    period = study.specimens.set_index("specimen")["wavelength_mm"]
    out = pd.DataFrame({"study": folder.name, "specimen": rows["specimen"].to_numpy(),
                        "period_mm": rows["specimen"].map(period).to_numpy(dtype=float),
                        "read_mm": np.exp(-loaded.features(X)[:, 0]),
                        "outside_mm": [r.period_mm for r in readings],
                        "band": [r.dominance >= DOMINANCE for r in readings],
                        "family": [bool(r) for r in loaded.applicability(X)],
                        "withheld": table["withheld"].to_numpy(),
                        "flagged": (table["withheld"] | table["extrapolates"]).to_numpy(),
                        "pred": loaded.predict(X),
                        "panel": rows["specimen"].map(panel).fillna(1.0).to_numpy(dtype=float)})
    out["right"] = np.abs(np.log(out["read_mm"] / out["period_mm"])) < RIGHT_LOG
    out["log_error"] = np.abs(np.log(out["pred"] / out["panel"]))
    return out


def cause(row) -> str:
    """The first test that fired on a flagged press (module docstring)."""
    if row.withheld:
        return "gate: withheld"
    if row.band:
        if 0.3 <= row.outside_mm <= 0.36 or 0.18 <= row.outside_mm <= 0.22:
            return "band: ridges' 3rd/5th harmonic"
        return "band: coarse shading" if row.outside_mm > 8 else "band: other"
    return "peak law domain" if row.family else "other"


def report(presses: pd.DataFrame) -> None:
    flagged = presses[presses["flagged"]].copy()
    flagged["cause"] = [cause(r) for r in flagged.itertuples()]
    n = len(presses)
    print(f"{n} presses read alone; withheld or flagged {len(flagged)} ({len(flagged) / n:.1%}); peak misread on "
          f"{int((~presses['right']).sum())}, of them flagged {int((~flagged['right']).sum())}")
    for name, group in flagged.groupby("cause"):
        print(f"  {name:32s} {len(group):3d}: read right {int(group['right'].sum()):2d} (|log error| median "
              f"{group.loc[group['right'], 'log_error'].median():.2f}), misread {int((~group['right']).sum()):2d} "
              f"(median {group.loc[~group['right'], 'log_error'].median():.2f}); specimens "
              f"{group['specimen'].value_counts().to_dict()}")
    ok = presses[~presses["flagged"]]
    print(f"  unflagged: |log error| median {ok['log_error'].median():.2f}, 90th percentile "
          f"{ok['log_error'].quantile(0.9):.2f}; misread and unflagged {int((~ok['right']).sum())}")
    right = int(flagged["right"].sum())
    print(f"  at best (every flag on a press read right removed): {len(flagged) - right} ({(len(flagged) - right) / n:.1%})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", required=True, help="the fingerprint pad's model file (fit, 2N)")
    parser.add_argument("--studies", type=Path, nargs="+", required=True, help="study folders (simulate --seed K)")
    args = parser.parse_args()
    report(pd.concat([press_table(args.model, folder) for folder in args.studies], ignore_index=True))


if __name__ == "__main__":
    main()
