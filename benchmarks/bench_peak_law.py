"""Benchmark the peak power law (the default model) against issue 35's goals, on the seeds the choices were made on
and on seeds nobody looked at.

For each seed of the built-in simulated study (paper's ratings), each pad and each condition (1N, 2N, 3N, combined),
three held-out schemes (analysis/held_out.py's folds and scores): a grating left out (LOSO), a period left out
(both shapes) and a shape left out (one row per held-out shape):
- mean per-specimen RMSE of the law, of the paper's PLS (LOSO only; component count nested, as the study) and of the
  training mean under the same folds; bias (rating units) and mean log bias per shape; Spearman rho (13 rated);
- the permutation p: 199 specimen-level shufflings (``controls.specimen_permutations`` from the study's seed), the
  whole cross-validation rerun on each, p = (1 + #shuffled CV RMSE <= real) / 200 on the pooled trial RMSE;
- the share of held-out presses the law's domain flags; the 90 % surface interval (jackknife+ over specimens, the
  fully nested check of model/jackknife_plus.py): coverage and median width; a held-out surface read from 1, 3, 5,
  10 presses (analysis/presses.py).
Seeds 0, 1 and 2 are the ones every choice was made on (the features, detector, Huber fit, domain, terms); seeds 3,
4 and 5 were not looked at: they redraw the twin's noise on the same 14 surfaces (not new surfaces).

Speed (one BLAS thread for every contender, as the study's controls run): ``peak_law_cv`` on 200 target columns
(the real ratings + 199 shufflings) of the largest model (smooth, combined: 140 trials x 135 amplitudes, 14 LOSO
folds) against a peer loop of scikit-learn ``HuberRegressor`` refits (epsilon 1.345, no L2 penalty) on the same two
features, one per fold and target, and against a loop of ``PeakPowerLaw`` refits (the same arithmetic unbatched; it
also checks that both agree). The batch is timed before and after the peers; the ratios use the slower median.

``--intervals-only``: the 90 % jackknife+ alone, fully nested, per surface and read from 1, 3, 5 presses, with the
specimens it misses and the folds that set its bounds (what ``fit`` stores and ``predict`` applies).

Run: .venv/bin/python benchmarks/bench_peak_law.py [--seeds 0 1 2 3 4 5] [--repeats 5] [--peer-targets 200]
     [--speed-only | --accuracy-only | --intervals-only] [--csv out.csv]
(ROUGHSENSE_CACHE_DIR selects the cache; each seed's study is simulated there on first use, ~20 s.)
"""
from __future__ import annotations

import argparse
import os
import platform
import statistics
import time

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

REPORTED_SEEDS = (0, 1, 2)
HELD_OUT_SEEDS = (3, 4, 5)
CONDITIONS = ("1N", "2N", "3N", "combined")
LOSO_GOAL = {"smooth": 0.18, "fingerprint": 0.20}  # issue 35 (issue 27 asked 0.20 / 0.22)
P_GOAL = 0.01
RHO_GOAL = 0.9
#: ... on at least this many of the 6 seeds (per pad x condition)
RHO_SEEDS = 5
#: Mean log(predicted / perceived) of each shape's specimens under LOSO.
BIAS_GOAL = 0.05
#: A period left out (both shapes): mean per-specimen RMSE.
LOPO_GOAL = 0.22
#: A shape left out: this share of the other shape's presses flagged, or RMSE and |bias| (rating units) within these.
SHAPE_FLAG_GOAL = 0.8
SHAPE_RMSE_GOAL = 0.20
SHAPE_BIAS_GOAL = 0.1
SHAPE_UNFLAGGED_BIAS = 0.15
#: The 90 % surface interval (jackknife+, fully nested): coverage of held-out specimens and its median width factor.
COVERAGE_GOAL = (0.85, 0.95)
WIDTH_GOAL = 1.6
#: A held-out fingerprint surface read from one press (analysis/presses.py).
ONE_PRESS_GOAL = 0.25
N_PERMUTATIONS = 199
MAX_COMPONENTS = 20


def study_of(seed: int):
    """The built-in study of ``seed`` (simulated on first use), its cached features and perceived roughness."""
    from roughsense._util import cache
    from roughsense.analysis import dataset
    from roughsense.cli._studies import builtin_study
    from roughsense.io.study import read_study

    study = read_study(builtin_study(seed, 2), require_ratings=True)
    definition = dataset.spectrum_for(study).feature_definition()
    features, _ = cache.cached_frame(cache.features_key(study, definition),
                                     lambda: dataset.study_features(study, n_jobs=2))
    return study, features, dataset.perceived_roughness(study)


def condition_cells(seeds):
    """Every seed x pad x condition of the built-in study, as the benchmarks of the law walk them: a dict of the
    study, its features, the condition's design matrix X, perceived targets y, each row's specimen, and shapes."""
    from roughsense.analysis import dataset

    for seed in seeds:
        study, features, perceived = study_of(seed)
        shapes = dict(zip(study.specimens["specimen"], study.specimens["shape"]))
        for pad in study.pads:
            for condition in CONDITIONS:
                X, meta = dataset.condition_matrix(features, pad, condition)
                yield {"seed": seed, "study": study, "features": features, "pad": pad, "condition": condition,
                       "X": X, "y": dataset.targets(meta, perceived), "shapes": shapes,
                       "specimens": meta["specimen"].astype(str).to_numpy()}


def law_settings(study, features, pad: str, condition: str, specimens=None) -> dict:
    """The study's own peak-law settings; with ``specimens``, a specimen's presses share its peak (as the study)."""
    from roughsense.analysis import dataset

    return {"freq_per_mm": dataset.column_frequencies(dataset.frequency_columns(features)),
            "n_blocks": 3 if condition == "combined" else 1,
            "pad_ridge_period_mm": study.pad_ridge_period_mm.get(pad),
            "surfaces": None if specimens is None else np.asarray(specimens)}


def pls_loso(X, Y, specimens) -> np.ndarray:
    """Nested LOSO predictions (B, n) of the paper's PLS for each column of Y, as model.pls.family.loso_nested."""
    from roughsense.model.pls.cv import nested_group_predictions, pls_cv_many

    held_out = int(pd.Series(specimens).value_counts().max())
    usable = int(min(MAX_COMPONENTS, len(specimens) - held_out - 1, X.shape[1]))
    outer = pls_cv_many(X, Y, max_components=usable, groups=specimens, cap=True)
    nested, _ = nested_group_predictions(X, Y, specimens, outer.predictions)
    return nested


def null_loso(y, specimens) -> np.ndarray:
    """The training mean of every LOSO fold, predicted for the held-out specimen."""
    out = np.empty_like(y)
    for name in np.unique(specimens):
        held = specimens == name
        out[held] = y[~held].mean()
    return out


def judge(prediction, y, meta, perceived, reference: str) -> dict:
    """Mean per-specimen RMSE (all specimens, as results_loso.csv) and Spearman rho over the rated ones."""
    from scipy.stats import spearmanr

    from roughsense.analysis.metrics import specimen_table

    frame = meta[["specimen"]].assign(prediction=prediction)
    table = specimen_table(frame, perceived, pred_sd_ddof=0)
    rated = table[table["specimen"] != reference]
    return {"rmse": float(table["rmse"].mean()), "rho": float(spearmanr(rated["pred_mean"], rated["gmean"])[0])}


def permutation_p(real, shuffled, y, Y) -> float:
    """p of the real pooled CV RMSE among the shuffled targets' (controls.control_row's rule, ties included)."""
    rmse = np.sqrt(np.mean((real - y) ** 2))
    permuted = np.sqrt(np.mean((shuffled - Y.T) ** 2, axis=1))
    return float((1 + np.sum(permuted <= rmse * (1 + 1e-12))) / (1 + permuted.size))


def evaluate_model(study, features, perceived, pad: str, condition: str, seed: int) -> list[dict]:
    """Both models and the null of one seed x pad x condition under LOSO, and the law with a period and a shape
    left out (analysis/held_out.py's folds and scores): RMSE, bias, log bias per shape, rho, p, the 90 % interval's
    coverage of held-out specimens, and the share of held-out presses the law's domain flags."""
    from roughsense.analysis import controls, dataset
    from roughsense.analysis.held_out import judged as scheme_scores
    from roughsense.analysis.held_out import scheme_folds
    from roughsense.analysis.presses import presses_curve
    from roughsense.model.interval import held_out_coverage
    from roughsense.model.jackknife_plus import nested_check
    from roughsense.model.peak_law.cv import law_domain_flags, peak_law_cv
    from roughsense.model.peak_law.folds import law_pair_log_predictions, specimen_codes

    X, meta = dataset.condition_matrix(features, pad, condition)
    y = dataset.targets(meta, perceived)
    specimens = meta["specimen"].astype(str).to_numpy()
    perms = controls.specimen_permutations(len(pd.unique(specimens)), N_PERMUTATIONS, seed)
    Y = controls.permuted_targets(y, specimens, perms)
    both = np.column_stack([y, Y])
    settings = law_settings(study, features, pad, condition, specimens)
    shapes = dict(zip(study.specimens["specimen"], study.specimens["shape"]))
    wavelengths = dict(zip(study.specimens["specimen"], study.specimens["wavelength_mm"].astype(float)))
    null = judge(null_loso(y, specimens), y, meta, perceived, study.reference_specimen)
    codes, names = specimen_codes(specimens)
    check = nested_check(law_pair_log_predictions(X, y, specimens, **settings),
                         np.log(pd.Series(y).groupby(codes).first().to_numpy()), names)
    curve = presses_curve(X, y, specimens, settings, seed).set_index("n_presses")["rmse"]
    jackknife = {"jk_coverage": float(check["covered"].mean()),
                 "jk_factor": float(np.exp(check["log_halfwidth"].median())),
                 "jk_misses": " ".join(check.loc[~check["covered"], "specimen"]),
                 **{f"presses_{k}": float(v) for k, v in curve.items()}}
    rows = []
    for scheme in ("specimen", "period", "shape"):
        folds = scheme_folds(scheme, specimens, shapes, wavelengths)
        law = peak_law_cv(X, both, groups=folds, **settings)
        flags = pd.Series(law_domain_flags(X, y, folds, **settings), index=specimens)
        contenders = (("peak-law", law), ("pls", pls_loso(X, both, specimens))) if scheme == "specimen" else \
            (("peak-law", law),)
        parts = [("all", np.ones(len(y), bool))] if scheme != "shape" else [(f, folds == f) for f in pd.unique(folds)]
        for model, predictions in contenders:
            trials, surfaces = held_out_coverage(predictions[0], y, specimens)
            is_law = model == "peak-law"
            for held, rows_in in parts:  # a shape left out: each direction on its own row
                extra = scheme_scores(predictions[0], y, specimens, folds, shapes, study.reference_specimen, rows_in)
                rows.append({"seed": seed, "pad": pad, "condition": condition, "scheme": scheme, "held_out": held,
                             "model": model, "rmse": extra["rmse"], "rho": extra["spearman_rho"],
                             "null_rmse": extra["null_rmse"] if scheme != "specimen" else null["rmse"],
                             "bias": extra["bias"], "log_bias_rectangular": extra.get("log_bias_rectangular", np.nan),
                             "log_bias_circular": extra.get("log_bias_circular", np.nan),
                             "p": permutation_p(predictions[0], predictions[1:], y, Y),
                             "coverage_trials": trials, "coverage_specimens": surfaces,
                             "flagged_share": float(flags[rows_in].mean()) if is_law else float("nan"),
                             "flagged_max": float(flags.groupby(level=0).mean().max()) if is_law else float("nan"),
                             **(jackknife if is_law and scheme == "specimen" else {})})
    return rows


def accuracy_table(seeds) -> pd.DataFrame:
    rows = []
    for seed in seeds:
        started = time.perf_counter()
        study, features, perceived = study_of(seed)
        for pad in study.pads:
            for condition in CONDITIONS:
                rows.extend(evaluate_model(study, features, perceived, pad, condition, seed))
        print(f"seed {seed}: {time.perf_counter() - started:.1f} s (study from the cache, 8 models x 200 targets x "
              "3 schemes)", flush=True)
    return pd.DataFrame(rows)


#: Presses per surface the interval check reads (10: a specimen's every press, the surface check).
INTERVAL_PRESSES = (1, 3, 5)


def bound_setters(pairs: np.ndarray, log_targets: np.ndarray, names) -> tuple[str, str, float]:
    """Which specimen's fold sets the nested jackknife+ bounds most often (upper, lower), and the share of held-out
    specimens whose upper bound it sets: the width is the extremes over 13 folds, so one specimen can own it."""
    upper, lower = [], []
    for t in range(len(names)):
        others = np.array([s for s in range(len(names)) if s != t])
        residuals = np.abs(log_targets[others] - pairs[t, others, others])
        centres = pairs[t, others, t]
        upper.append(names[others[np.argmax(centres + residuals)]])
        lower.append(names[others[np.argmin(centres - residuals)]])
    top_upper = pd.Series(upper).value_counts()
    top_lower = pd.Series(lower).value_counts()
    return (f"{top_upper.index[0]} ({top_upper.iloc[0]}/{len(names)})", f"{top_lower.index[0]} "
            f"({top_lower.iloc[0]}/{len(names)})", float(top_upper.iloc[0] / len(names)))


def interval_rows(study, features, perceived, pad: str, condition: str, seed: int) -> dict:
    """The 90 % jackknife+ (the default model) fully nested: a surface's (every press) and one read from 1, 3, 5
    presses (model/peak_law/folds.py's check, as fit stores and predict applies them), with the specimens it misses
    and the folds that set its bounds."""
    from roughsense.analysis import dataset
    from roughsense.model.jackknife_plus import nested_check
    from roughsense.model.peak_law.folds import law_nested_press_check, law_pair_log_predictions, law_pair_models, specimen_codes

    X, meta = dataset.condition_matrix(features, pad, condition)
    y = dataset.targets(meta, perceived)
    specimens = meta["specimen"].astype(str).to_numpy()
    settings = law_settings(study, features, pad, condition, specimens)
    codes, names = specimen_codes(specimens)
    log_targets = np.log(pd.Series(y).groupby(codes).first().to_numpy())
    models = law_pair_models(X, y, specimens, **settings)
    pairs = law_pair_log_predictions(X, y, specimens, models=models, **settings)
    check = nested_check(pairs, log_targets, names)
    upper, lower, upper_share = bound_setters(pairs, log_targets, names)
    row = {"seed": seed, "pad": pad, "condition": condition, "coverage": float(check["covered"].mean()),
           "factor": float(np.exp(check["log_halfwidth"].median())), "upper_set_by": upper, "lower_set_by": lower,
           "upper_share": upper_share, "misses": " ".join(
               f"{r.specimen} x{np.exp(r.miss_log):.2f}" for r in check[~check["covered"]].itertuples())}
    for count in INTERVAL_PRESSES:
        press = law_nested_press_check(X, y, specimens, count, seed, models=models, **settings)
        row[f"coverage_{count}"] = float(np.average(press["covered"], weights=press["readings"]))
        row[f"factor_{count}"] = float(np.exp(press["log_halfwidth"].median()))
    return row


def interval_table(seeds) -> pd.DataFrame:
    rows = []
    for seed in seeds:
        study, features, perceived = study_of(seed)
        rows.extend(interval_rows(study, features, perceived, pad, condition, seed)
                    for pad in study.pads for condition in CONDITIONS)
    return pd.DataFrame(rows)


def print_intervals(frame: pd.DataFrame) -> None:
    """Per seed, pad and condition: coverage and median width (x/÷) of the nested 90 % jackknife+, per surface and
    read from 1, 3, 5 presses; then the goal per seed group, and what sets the width."""
    print("\n90 % jackknife+ over specimens, fully nested (leave-two-out). cover / x/÷ width: a surface (every press), "
          "and one read from 1, 3, 5 presses; the folds setting the upper and lower bound most often")
    for r in frame.itertuples():
        print(f"{r.seed:>4} {r.pad:>11} {r.condition:>8} | {r.coverage:.3f} {r.factor:5.2f} | "
              + " ".join(f"{getattr(r, f'coverage_{k}'):.3f} {getattr(r, f'factor_{k}'):5.2f}"
                         for k in INTERVAL_PRESSES)
              + f" | up {r.upper_set_by}, low {r.lower_set_by} | misses {r.misses or '-'}")
    for label, seeds in (("seeds 0-2 (looked at)", REPORTED_SEEDS), ("seeds 3-5 (held out)", HELD_OUT_SEEDS)):
        part = frame[frame.seed.isin(seeds)]
        if part.empty:
            continue
        ok = part.coverage.between(*COVERAGE_GOAL) & (part.factor <= WIDTH_GOAL)
        print(f"{_verdict(ok)} {label}: coverage {part.coverage.min():.3f}-{part.coverage.max():.3f} (goal "
              f"{COVERAGE_GOAL[0]}-{COVERAGE_GOAL[1]}), median width x/÷ {part.factor.min():.2f}-{part.factor.max():.2f} "
              f"(goal <= {WIDTH_GOAL}; {int((part.factor <= WIDTH_GOAL).sum())} of {len(part)} cells within); "
              f"1 press: coverage {part.coverage_1.min():.3f}-{part.coverage_1.max():.3f}, width "
              f"{part.factor_1.min():.2f}-{part.factor_1.max():.2f}")


def print_table(frame: pd.DataFrame) -> None:
    print("\nMean per-specimen RMSE (null = training mean, same folds), bias (rating units), mean log bias per shape "
          "(rect / circ), permutation p (199), Spearman rho (13 rated), coverage of the 90 % interval (trials), "
          "share of held-out presses flagged")
    print(f"{'seed':>4} {'pad':>11} {'cond':>8} {'scheme':>8} | {'law':>6} {'null':>6} {'bias':>6} {'rect':>6} "
          f"{'circ':>6} {'p':>6} {'rho':>5} {'cover':>5} {'flag':>5} | {'PLS':>6} {'p':>6} {'rho':>5}")
    for (seed, pad, condition, scheme, held), group in frame.groupby(["seed", "pad", "condition", "scheme", "held_out"],
                                                                       sort=False):
        law = group[group.model == "peak-law"].iloc[0]
        scheme = scheme if held == "all" else f"{held[:4]}."
        pls = group[group.model == "pls"]
        tail = f"{pls.rmse.iloc[0]:6.3f} {pls.p.iloc[0]:6.3f} {pls.rho.iloc[0]:5.2f}" if len(pls) else ""
        print(f"{seed:>4} {pad:>11} {condition:>8} {scheme:>8} | {law.rmse:6.3f} {law.null_rmse:6.3f} {law.bias:+6.3f} "
              f"{law.log_bias_rectangular:+6.3f} {law.log_bias_circular:+6.3f} {law.p:6.3f} {law.rho:5.2f} "
              f"{law.coverage_trials:5.2f} {law.flagged_share:5.2f} | {tail}")


def _verdict(ok: pd.Series) -> str:
    return "PASS" if bool(ok.all()) else "MISS"


def _misses(part: pd.DataFrame, ok: pd.Series, value) -> str:
    where = "; ".join(f"seed {r.seed} {r.pad} {r.condition} {value(r)}" for r in part[~ok].itertuples())
    return f" -- misses: {where}" if where else ""


def print_goals(frame: pd.DataFrame) -> None:
    """One PASS/MISS line per goal of issue 35 and seed group, naming every cell that misses (the default model)."""
    law = frame[frame.model == "peak-law"]
    print("\nIssue 35 goals for the default model, the peak law (each pad x 1N, 2N, 3N, combined). The held-out seeds "
          "redraw the twin's noise on the same 14 surfaces; they are not new surfaces.")
    for label, seeds in (("seeds 0-2 (looked at)", REPORTED_SEEDS), ("seeds 3-5 (held out)", HELD_OUT_SEEDS)):
        part = law[law.seed.isin(seeds)]
        if part.empty:
            continue
        loso, lopo, losho = (part[part.scheme == s] for s in ("specimen", "period", "shape"))
        ok = loso.rmse <= loso.pad.map(LOSO_GOAL)
        print(f"{_verdict(ok)} {label}: LOSO RMSE <= 0.18 smooth / 0.20 fingerprint"
              + _misses(loso, ok, lambda r: f"{r.rmse:.3f}"))
        ok = (loso.log_bias_rectangular.abs() <= BIAS_GOAL) & (loso.log_bias_circular.abs() <= BIAS_GOAL)
        print(f"{_verdict(ok)} {label}: LOSO mean log bias per shape within +-{BIAS_GOAL}" + _misses(
            loso, ok, lambda r: f"rect {r.log_bias_rectangular:+.3f} circ {r.log_bias_circular:+.3f}"))
        ok = (lopo.rmse <= LOPO_GOAL) & (lopo.rmse < lopo.null_rmse) & (lopo.p <= P_GOAL)
        print(f"{_verdict(ok)} {label}: a period left out: RMSE <= {LOPO_GOAL}, below the training mean, p <= {P_GOAL}"
              + _misses(lopo, ok, lambda r: f"{r.rmse:.3f} (null {r.null_rmse:.3f}, p {r.p:.3f})"))
        flagged = losho.flagged_share >= SHAPE_FLAG_GOAL
        ok = flagged | ((losho.rmse <= SHAPE_RMSE_GOAL) & (losho.bias.abs() <= SHAPE_BIAS_GOAL))
        print(f"{_verdict(ok)} {label}: a shape left out: >= {SHAPE_FLAG_GOAL:.0%} flagged, or RMSE <= "
              f"{SHAPE_RMSE_GOAL} with |bias| <= {SHAPE_BIAS_GOAL}" + _misses(
                  losho, ok, lambda r: f"{r.rmse:.3f} bias {r.bias:+.3f} flagged {r.flagged_share:.0%}"))
        ok = flagged | (losho.bias.abs() <= SHAPE_UNFLAGGED_BIAS)
        print(f"{_verdict(ok)} {label}: a shape left out: never an unflagged |bias| > {SHAPE_UNFLAGGED_BIAS}" + _misses(
            losho, ok, lambda r: f"bias {r.bias:+.3f} flagged {r.flagged_share:.0%}"))
        ok = loso.jk_coverage.between(*COVERAGE_GOAL) & (loso.jk_factor <= WIDTH_GOAL)
        print(f"{_verdict(ok)} {label}: 90 % surface interval (jackknife+, nested): coverage {COVERAGE_GOAL[0]:.0%}-"
              f"{COVERAGE_GOAL[1]:.0%}, median width <= x/÷ {WIDTH_GOAL}" + _misses(
                  loso, ok, lambda r: f"{r.jk_coverage:.3f} x/÷ {r.jk_factor:.2f} (misses {r.jk_misses})"))
        fingerprint = loso[loso.pad == "fingerprint"]
        ok = fingerprint.presses_1 <= ONE_PRESS_GOAL
        print(f"{_verdict(ok)} {label}: one fingerprint press per surface: LOSO RMSE <= {ONE_PRESS_GOAL}" + _misses(
            fingerprint, ok, lambda r: f"{r.presses_1:.3f} (3 presses {r.presses_3:.3f}, 10 {r.presses_10:.3f})"))
    loso = law[law.scheme == "specimen"]
    seeds_ok = (loso.rho >= RHO_GOAL).groupby([loso.pad, loso.condition]).sum()
    print(f"{_verdict(seeds_ok >= RHO_SEEDS)} LOSO rho >= {RHO_GOAL} on at least {RHO_SEEDS} of the seeds, per pad x "
          "condition: " + ", ".join(f"{pad} {cond} {int(n)}" for (pad, cond), n in seeds_ok.items()))


def speed(repeats: int, peer_targets: int) -> None:
    """peak_law_cv on 200 targets against per-fold refit loops (HuberRegressor; PeakPowerLaw), smooth combined."""
    from sklearn.linear_model import HuberRegressor

    from roughsense.analysis import controls, dataset
    from roughsense.model.peak_law.cv import peak_law_cv
    from roughsense.model.peak_law.law import PeakPowerLaw
    from roughsense.model.peak_search import peak_features

    study, features, perceived = study_of(0)
    X, meta = dataset.condition_matrix(features, "smooth", "combined")
    y = dataset.targets(meta, perceived)
    specimens = meta["specimen"].astype(str).to_numpy()
    perms = controls.specimen_permutations(len(pd.unique(specimens)), N_PERMUTATIONS, 0)
    Y = np.column_stack([y, controls.permuted_targets(y, specimens, perms)])
    settings = law_settings(study, features, "smooth", "combined", specimens)
    ours = _median_time(lambda: peak_law_cv(X, Y, groups=specimens, **settings), repeats)
    batched = peak_law_cv(X, Y, groups=specimens, **settings)
    F = peak_features(X, **settings)
    fit_settings = {k: v for k, v in settings.items() if k != "surfaces"}

    def huber_loop():
        for b in range(peer_targets):
            for name in np.unique(specimens):
                train = specimens != name
                HuberRegressor(epsilon=1.345, alpha=0.0).fit(F[train], np.log(Y[train, b])).predict(F[~train])

    def law_loop():
        out = np.empty((peer_targets, len(y)))
        for b in range(peer_targets):
            for name in np.unique(specimens):
                held = specimens == name
                out[b, held] = PeakPowerLaw(**fit_settings).fit(X[~held], Y[~held, b], surfaces=specimens[~held]).predict(
                    X[held], surfaces=specimens[held])
        return out

    peer = _median_time(huber_loop, max(1, repeats // 2)) * Y.shape[1] / peer_targets
    refit = _median_time(law_loop, max(1, repeats // 2)) * Y.shape[1] / peer_targets
    ours_again = _median_time(lambda: peak_law_cv(X, Y, groups=specimens, **settings), repeats)
    agree = np.max(np.abs(law_loop() / batched[:peer_targets] - 1))
    print(f"\nspeed, smooth combined (140 x 135), LOSO 14 folds x {Y.shape[1]} targets:")
    print(f"  peak_law_cv (batched, features included): {1000 * ours:8.1f} ms (median of {repeats}, before the "
          f"peers; {1000 * ours_again:.1f} ms after them)")
    ours = max(ours, ours_again)  # the ratios take the slower of the two medians
    print(f"  HuberRegressor refit per fold and target: {1000 * peer:8.1f} ms ({peer_targets} targets timed, scaled): "
          f"{peer / ours:6.0f}x")
    print(f"  PeakPowerLaw refit per fold and target:   {1000 * refit:8.1f} ms: {refit / ours:6.0f}x; "
          f"max relative difference from the batch {agree:.1e}")


def _median_time(call, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        call()
        times.append(time.perf_counter() - started)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[*REPORTED_SEEDS, *HELD_OUT_SEEDS])
    parser.add_argument("--repeats", type=int, default=5, help="timed runs of the batched CV (median)")
    parser.add_argument("--peer-targets", type=int, default=200, help="targets the refit loops are timed on")
    parser.add_argument("--csv", help="write the accuracy table here too")
    parser.add_argument("--speed-only", action="store_true", help="skip the accuracy table (speed comparison only)")
    parser.add_argument("--accuracy-only", action="store_true", help="skip the speed comparison")
    parser.add_argument("--intervals-only", action="store_true",
                        help="only the nested 90 %% jackknife+ (per surface and from 1, 3, 5 presses)")
    args = parser.parse_args()
    print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"load average {os.getloadavg()[0]:.1f} at start")
    if args.intervals_only:
        frame = interval_table(args.seeds)
        print_intervals(frame)
        if args.csv:
            frame.to_csv(args.csv, index=False)
        return
    if not args.speed_only:
        frame = accuracy_table(args.seeds)
        print_table(frame)
        print_goals(frame)
        if args.csv:
            frame.to_csv(args.csv, index=False)
    if not args.accuracy_only:
        with threadpool_limits(1):  # as the study's controls run (one BLAS thread); the peers get the same
            speed(args.repeats, args.peer_targets)
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
