"""Which terms earn their place in the law: an ablation under leave-one-specimen-out and leave-one-period-out.

For each seed of the built-in study (paper's ratings), pad and condition, four term sets are fitted by the law's
own Huber IRLS (``peak_law.huber_irls``, epsilon 1.345) on the law's features, each fold's features held to its
training range (as the law clips to its domain):

- ``period``: log peak frequency alone (the law without its amplitude term);
- ``law``: log peak frequency and log peak amplitude (the default model's terms);
- ``period+harmonic``: log peak frequency and the second harmonic's log ratio (sensor/shape.py), the shape term;
- ``law+harmonic``: all three.

The harmonic ratio is read on each surface's mean spectrum (where its peak is read). A term set is formed on a pad
only where the ratio is readable for every surface (on a fingerprint pad a 2 mm grating's second harmonic sits on
the pad's ridges: unreadable), else it is reported as not formed. Reported: mean per-specimen RMSE and the mean log
bias of each shape. The term sets are judged on seeds 0-2 (``--seeds 0 1 2``) and the choice is then reported on
3-5, which redraw the twin's noise on the same 14 surfaces (not new surfaces).

``--flags``: the domain's flags press by press instead (model/press_spread.py). Per seed, pad and condition, the
law fitted on all 14 specimens (surfaces given), each training press then read *alone*: the share flagged with the
training presses' scatter (``press_scatter_``) and without it (surface margins only), by reason; and a shape left
out (the law fitted on one shape), the share of the other shape's presses flagged, read alone and read together.

Run: .venv/bin/python benchmarks/bench_shape_terms.py [--seeds 0 1 2] [--csv out.csv] [--flags]
"""
from __future__ import annotations

import argparse
import os
import platform

import numpy as np
import pandas as pd

from bench_peak_law import condition_cells, law_settings

TERM_SETS = ("period", "law", "period+harmonic", "law+harmonic")


def term_features(X, settings: dict, specimens) -> dict[str, np.ndarray | None]:
    """Each term set's design columns (n, p); None where the harmonic ratio cannot be read on every surface."""
    from roughsense.model.peak_law.folds import specimen_codes
    from roughsense.model.peak_search import peak_features
    from roughsense.sensor.shape import harmonic_ratio

    features = peak_features(X, **settings)
    freq, n_blocks = settings["freq_per_mm"], settings["n_blocks"]
    codes, names = specimen_codes(specimens)
    spectra = X.reshape(len(X), n_blocks, freq.size).mean(axis=1)
    surface = np.stack([spectra[codes == c].mean(axis=0) for c in range(names.size)])
    ratio = harmonic_ratio(np.log(np.maximum(surface, 1e-300)), freq, np.exp(features[:, 0])[np.unique(
        codes, return_index=True)[1]], settings["pad_ridge_period_mm"])[codes]
    readable = bool(np.all(np.isfinite(ratio)))
    return {"period": features[:, :1], "law": features,
            "period+harmonic": np.column_stack([features[:, 0], ratio]) if readable else None,
            "law+harmonic": np.column_stack([features, ratio]) if readable else None}


def clipped_cv(design: np.ndarray, log_y: np.ndarray, folds: np.ndarray) -> np.ndarray:
    """Out-of-fold predictions of a Huber fit per fold, each fold's features held to its training range."""
    from roughsense.model.huber_batch import huber_irls

    names, fold_of = np.unique(folds, return_inverse=True)
    held = fold_of[None, :] == np.arange(names.size)[:, None]
    beta, _ = huber_irls(design, log_y[None], ~held)
    prediction = np.empty_like(log_y)
    for k, rows in enumerate(held):
        train = design[~rows]
        clipped = np.clip(design[rows], train.min(axis=0), train.max(axis=0))
        prediction[rows] = beta[k, 0, 0] + clipped @ beta[k, 0, 1:]
    return np.exp(prediction)


def scores(prediction, y, specimens, shapes: dict) -> dict:
    frame = pd.DataFrame({"s": specimens, "e": (prediction - y) ** 2, "b": np.log(prediction) - np.log(y)})
    per = frame.groupby("s").mean()
    shape = per.index.map(shapes)
    return {"rmse": float(np.sqrt(per["e"]).mean()), "bias_rect": float(per["b"][shape == "rectangular"].mean()),
            "bias_circ": float(per["b"][shape == "circular"].mean())}


def ablation(seeds) -> pd.DataFrame:
    rows = []
    for cell in condition_cells(seeds):
        X, y, specimens, study = cell["X"], cell["y"], cell["specimens"], cell["study"]
        periods = dict(zip(study.specimens["specimen"], study.specimens["wavelength_mm"]))
        settings = law_settings(study, cell["features"], cell["pad"], cell["condition"], specimens)
        for name, design in term_features(X, settings, specimens).items():
            for scheme, folds in (("loso", specimens), ("lopo", np.array([periods[s] for s in specimens]))):
                base = {"seed": cell["seed"], "pad": cell["pad"], "condition": cell["condition"], "terms": name,
                        "scheme": scheme}
                if design is None:
                    rows.append({**base, "rmse": np.nan, "bias_rect": np.nan, "bias_circ": np.nan})
                    continue
                rows.append({**base, **scores(clipped_cv(design, np.log(y), folds), y, specimens, cell["shapes"])})
    return pd.DataFrame(rows)


def _reason_kinds(reasons) -> dict:
    """Share of rows flagged for each kind of reason (a row may have several)."""
    kinds = {"period": "period ", "strength": "peak strength", "shape": "contact pattern", "clarity": "no clear peak",
             "agreement": "presses peak"}
    parts = [[part.split(" (")[0] for part in r.split("; ")] for r in reasons]
    return {kind: float(np.mean([any(p.startswith(word) or (kind != "period" and word in p) for p in row)
                                 for row in parts])) for kind, word in kinds.items()}


def flag_table(seeds) -> pd.DataFrame:
    """Training presses read alone (with and without the presses' scatter), and a shape left out (alone, together)."""
    from roughsense.model.peak_law.law import PeakPowerLaw

    rows = []
    for cell in condition_cells(seeds):
        X, y, specimens = cell["X"], cell["y"], cell["specimens"]
        settings = law_settings(cell["study"], cell["features"], cell["pad"], cell["condition"])
        settings.pop("surfaces")
        base = {"seed": cell["seed"], "pad": cell["pad"], "condition": cell["condition"]}
        law = PeakPowerLaw(**settings).fit(X, y, surfaces=specimens)
        with_spread = law.applicability(X)
        law.press_scatter_ = None  # the surface margins alone, as before the presses' scatter was kept
        rows.append({**base, "test": "training alone", "flagged": np.mean([bool(r) for r in with_spread]),
                     "flagged_surface_margins": np.mean([bool(r) for r in law.applicability(X)]),
                     **_reason_kinds(with_spread)})
        shape_of = np.array([cell["shapes"][s] for s in specimens])
        for trained in ("rectangular", "circular"):
            train = shape_of == trained
            one = PeakPowerLaw(**settings).fit(X[train], y[train], surfaces=specimens[train])
            alone = one.applicability(X[~train])
            together = one.applicability(X[~train], surfaces=specimens[~train])
            rows.append({**base, "test": f"{trained} trained, other shape",
                         "flagged": np.mean([bool(r) for r in alone]),
                         "flagged_together": np.mean([bool(r) for r in together]), **_reason_kinds(alone)})
    return pd.DataFrame(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--csv", help="write the table here too")
    parser.add_argument("--flags", action="store_true", help="the domain's flags press by press instead")
    args = parser.parse_args()
    print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    pd.set_option("display.width", 200)
    if args.flags:
        frame = flag_table(args.seeds)
        print("\nShare of presses flagged, read alone (flagged), by reason; surface margins only; other shape together")
        print(frame.round(3).to_string(index=False))
        print("\nWorst cell per pad and test:")
        print(frame.groupby(["pad", "test"])[["flagged", "flagged_surface_margins", "flagged_together", "shape"]]
              .agg(["min", "max"]).round(3).to_string())
        if args.csv:
            frame.to_csv(args.csv, index=False)
        return
    frame = ablation(args.seeds)
    for scheme in ("loso", "lopo"):
        part = frame[frame.scheme == scheme]
        print(f"\n{scheme.upper()}: mean per-specimen RMSE (NaN: the harmonic ratio is not readable on every surface)")
        print(part.pivot_table(index=["pad", "condition", "seed"], columns="terms", values="rmse", dropna=False)
              [list(TERM_SETS)].round(3).to_string())
        means = part.groupby(["pad", "terms"])[["rmse", "bias_rect", "bias_circ"]].mean().round(3)
        print(f"\n{scheme.upper()}, mean over seeds and conditions: RMSE and mean log bias per shape")
        print(means.to_string())
    if args.csv:
        frame.to_csv(args.csv, index=False)


if __name__ == "__main__":
    main()
