"""Benchmark the peak power law (the default model) against issue 27's goals, on the seeds the choices were made on
and on seeds nobody looked at.

For each seed of the built-in simulated study (paper's ratings), each pad and each condition (1N, 2N, 3N, combined),
under leave-one-specimen-out (LOSO):
- mean per-specimen RMSE of the peak law, of the paper's PLS (component count nested, exactly as
  analysis/study_analysis.py's ``_loso_nested``) and of the training mean (the null model);
- the permutation p of each model: 199 specimen-level shufflings (``controls.specimen_permutations`` from the
  study's seed), the whole LOSO rerun on each, p = (1 + #shuffled CV RMSE <= real) / 200 on the pooled trial
  RMSE, as controls.csv computes it;
- Spearman rho of the specimen-mean LOSO predictions against perceived roughness over the 13 rated specimens
  (the reference R3 is left out: its value is fixed by definition);
- the empirical coverage of the 90 % prediction interval on held-out specimens (model/interval.py), and the
  largest share of a held-out specimen's trials that the law's applicability domain flags.
Seeds 0, 1 and 2 are the ones the issues report, and the law's features, detector, Huber fit, clipping, reading a
specimen's peak from all its presses (issue 27) and the domain's margins were chosen while looking at them; seeds 3,
4 and 5 were not looked at (held out). Goals (issue 27): LOSO RMSE <= 0.20 smooth / <= 0.22 fingerprint, p <= 0.01
and below the training mean in every cell, rho >= 0.9 on at least 5 of 6 seeds, 85-95 % coverage (combined, seeds
0-2).

Speed (one BLAS thread for every contender, as the study's controls run): ``peak_law_cv`` on 200 target columns
(the real ratings + 199 shufflings) of the largest model (smooth, combined: 140 trials x 135 amplitudes, 14 LOSO
folds) against a peer loop of scikit-learn ``HuberRegressor`` refits (epsilon 1.345, no L2 penalty) on the same two
features, one per fold and target, and against a loop of ``PeakPowerLaw`` refits (the same arithmetic unbatched; it
also checks that both agree). The batch is timed before and after the peers; the ratios use the slower median.

Run: .venv/bin/python benchmarks/bench_peak_law.py [--seeds 0 1 2 3 4 5] [--repeats 5] [--peer-targets 200] [--speed-only]
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
RMSE_GOAL = {"smooth": 0.20, "fingerprint": 0.22}  # issue 27 (issue 19 asked 0.25 on the fingerprint pad)
P_GOAL = 0.01
RHO_GOAL = 0.9
#: ... on at least this many of the 6 seeds (per pad x condition)
RHO_SEEDS = 5
#: Empirical coverage of the 90 % interval on held-out specimens (trials), combined condition, seeds 0-2.
COVERAGE_GOAL = (0.85, 0.95)
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


def law_settings(study, features, pad: str, condition: str, specimens=None) -> dict:
    """The study's own peak-law settings; with ``specimens``, a specimen's presses share its peak (as the study)."""
    from roughsense.analysis import dataset

    return {"freq_per_mm": dataset.column_frequencies(dataset.frequency_columns(features)),
            "n_blocks": 3 if condition == "combined" else 1,
            "pad_ridge_period_mm": study.pad_ridge_period_mm.get(pad),
            "surfaces": None if specimens is None else np.asarray(specimens)}


def pls_loso(X, Y, specimens) -> np.ndarray:
    """Nested LOSO predictions (B, n) of the paper's PLS for each column of Y, as study_analysis._loso_nested."""
    from roughsense.model.pls_cv import nested_group_predictions, pls_cv_many

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
    """Both models and the null of one seed x pad x condition under LOSO: RMSE, rho, p, the 90 % interval's coverage
    of held-out specimens, and the largest share of a held-out specimen's trials the law's domain flags."""
    from roughsense.analysis import controls, dataset
    from roughsense.model.interval import held_out_coverage
    from roughsense.model.peak_law import held_out_flags, peak_law_cv

    X, meta = dataset.condition_matrix(features, pad, condition)
    y = dataset.targets(meta, perceived)
    specimens = meta["specimen"].astype(str).to_numpy()
    perms = controls.specimen_permutations(len(pd.unique(specimens)), N_PERMUTATIONS, seed)
    Y = controls.permuted_targets(y, specimens, perms)
    both = np.column_stack([y, Y])
    settings = law_settings(study, features, pad, condition, specimens)
    law = peak_law_cv(X, both, groups=specimens, **settings)
    pls = pls_loso(X, both, specimens)
    null = judge(null_loso(y, specimens), y, meta, perceived, study.reference_specimen)
    flags = pd.Series(held_out_flags(X, y, specimens, **settings), index=specimens).groupby(level=0).mean()
    rows = []
    for model, predictions in (("peak-law", law), ("pls", pls)):
        scores = judge(predictions[0], y, meta, perceived, study.reference_specimen)
        trials, surfaces = held_out_coverage(predictions[0], y, specimens)
        rows.append({"seed": seed, "pad": pad, "condition": condition, "model": model, **scores,
                     "null_rmse": null["rmse"], "p": permutation_p(predictions[0], predictions[1:], y, Y),
                     "coverage_trials": trials, "coverage_specimens": surfaces,
                     "flagged_max": float(flags.max()) if model == "peak-law" else float("nan")})
    return rows


def accuracy_table(seeds) -> pd.DataFrame:
    rows = []
    for seed in seeds:
        started = time.perf_counter()
        study, features, perceived = study_of(seed)
        for pad in study.pads:
            for condition in CONDITIONS:
                rows.extend(evaluate_model(study, features, perceived, pad, condition, seed))
        print(f"seed {seed}: {time.perf_counter() - started:.1f} s (study from the cache, 8 models x 200 targets each)",
              flush=True)
    frame = pd.DataFrame(rows)
    frame["goal_rmse"] = frame["pad"].map(RMSE_GOAL)
    frame["rmse_ok"] = frame["rmse"] <= frame["goal_rmse"]
    frame["p_ok"] = frame["p"] <= P_GOAL
    frame["null_ok"] = frame["rmse"] < frame["null_rmse"]
    frame["rho_ok"] = frame["rho"] >= RHO_GOAL
    frame["coverage_ok"] = frame["coverage_trials"].between(COVERAGE_GOAL[0], COVERAGE_GOAL[1])
    return frame


def print_table(frame: pd.DataFrame) -> None:
    print("\nLOSO, mean per-specimen RMSE (null = training mean), permutation p (199), Spearman rho (13 rated)")
    print(f"{'seed':>4} {'pad':>11} {'cond':>8} | {'law RMSE':>8} {'p':>6} {'rho':>5} {'cover':>5} {'flag':>4} | "
          f"{'PLS RMSE':>8} {'p':>6} {'rho':>5} {'cover':>5} | {'null':>5}")
    for (seed, pad, condition), group in frame.groupby(["seed", "pad", "condition"], sort=False):
        law = group[group.model == "peak-law"].iloc[0]
        pls = group[group.model == "pls"].iloc[0]
        print(f"{seed:>4} {pad:>11} {condition:>8} | {law.rmse:8.3f} {law.p:6.3f} {law.rho:5.2f} "
              f"{law.coverage_trials:5.2f} {law.flagged_max:4.1f} | {pls.rmse:8.3f} {pls.p:6.3f} {pls.rho:5.2f} "
              f"{pls.coverage_trials:5.2f} | {law.null_rmse:5.3f}")


def print_goals(frame: pd.DataFrame) -> None:
    """One PASS/MISS line per goal, seed group and pad, naming every model that misses (issue 27's goals)."""
    print("\nIssue 27 goals for the default model, the peak law (each pad x 1N, 2N, 3N, combined):")
    law = frame[frame.model == "peak-law"]
    goals = (("rmse_ok", "LOSO RMSE <= goal (0.20 smooth, 0.22 fingerprint)", "rmse"), ("p_ok", "p <= 0.01", "p"),
             ("null_ok", "beats the training mean", "rmse"), ("rho_ok", "Spearman rho >= 0.9", "rho"))
    for label, seeds in (("reported seeds 0-2", REPORTED_SEEDS), ("held-out seeds 3-5", HELD_OUT_SEEDS)):
        part = law[law.seed.isin(seeds)]
        if part.empty:
            continue
        for pad in part.pad.unique():
            at_pad = part[part.pad == pad]
            for column, text, value in goals:
                misses = at_pad[~at_pad[column]]
                verdict = "PASS" if misses.empty else "MISS"
                where = "; ".join(f"seed {r.seed} {r.condition} {getattr(r, value):.3f}" for r in misses.itertuples())
                print(f"{verdict} {label:>18} {pad:>11}: {text}" + (f" -- misses: {where}" if where else ""))
    seeds_ok = law.groupby(["pad", "condition"])["rho_ok"].sum()
    verdict = "PASS" if (seeds_ok >= RHO_SEEDS).all() else "MISS"
    print(f"{verdict} rho >= {RHO_GOAL} on at least {RHO_SEEDS} of the seeds, per pad x condition: "
          + ", ".join(f"{pad} {cond} {int(n)}" for (pad, cond), n in seeds_ok.items()))
    combined = law[(law.condition == "combined") & law.seed.isin(REPORTED_SEEDS)]
    verdict = "PASS" if combined["coverage_ok"].all() else "MISS"
    print(f"{verdict} 90 % interval covers {COVERAGE_GOAL[0]:.0%}-{COVERAGE_GOAL[1]:.0%} of held-out trials, combined, "
          "seeds 0-2: " + ", ".join(f"seed {r.seed} {r.pad} {r.coverage_trials:.3f} (specimens {r.coverage_specimens:.2f})"
                                     for r in combined.itertuples()))
    held = law[law.condition == "combined"]
    print("  (seeds 3-5, held out: " + ", ".join(f"seed {r.seed} {r.pad} {r.coverage_trials:.3f}"
                                                 for r in held[held.seed.isin(HELD_OUT_SEEDS)].itertuples()) + ")")
    print(f"largest share of a held-out specimen's trials the law flags: {law['flagged_max'].max():.2f} "
          "(goal < 0.20)")


def speed(repeats: int, peer_targets: int) -> None:
    """peak_law_cv on 200 targets against per-fold refit loops (HuberRegressor; PeakPowerLaw), smooth combined."""
    from sklearn.linear_model import HuberRegressor

    from roughsense.analysis import controls, dataset
    from roughsense.model.peak_law import PeakPowerLaw, peak_features, peak_law_cv

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
    args = parser.parse_args()
    print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"load average {os.getloadavg()[0]:.1f} at start")
    if not args.speed_only:
        frame = accuracy_table(args.seeds)
        print_table(frame)
        print_goals(frame)
        if args.csv:
            frame.to_csv(args.csv, index=False)
    with threadpool_limits(1):  # as the study's controls run (one BLAS thread); the peers get the same
        speed(args.repeats, args.peer_targets)
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
