"""Issue 46's goals ("Read the groove"), measured on the twin for every registered model family and each pad.

The figures are judged on seeds and gratings kept back (docs: /work plan of issue 46; the issue's "Goals"):

- **judging seeds** 7 and 11 (the default ``--seeds``); the **design seeds** 0, 1, 2 are the ones anything may be
  chosen on, and a run on them is labelled "design", never "judging";
- **kept-back gratings**: rectangles of the paper's periods whose land and groove differ (:data:`KEPT_BACK`: the
  issue's five, their mirrors, and two more), never in a training set.

For each seed S the script simulates the training set (``--train``; default the twin's ``paper+grooves`` set if
``simulate`` takes its name, else its explicit list :data:`PAPER_GROOVES`; ``paper`` is the paper's 14) and a study of
R3 (the panel's reference) plus the kept-back gratings, both with ``--seed S``; runs ``roughsense study`` on the
training set (``--permutations 0``: no goal reads a permutation p) and, per family and pad, ``roughsense fit``
(combined condition), then predicts the kept-back study with it (``rs.predict``, the table ``predict --study``
writes). Every family comes from the registry (``model/registry.py``); nothing is hard-coded but the goals' bars.

Goals, one table each, PASS/FAIL per family and pad:

(a) **Gratings of other land/groove widths.** Per surface: the mean of its presses' predictions against the panel's
    geometric mean. The error is the model's own reading of every press (the contact-image gate off: a model cannot
    pass the accuracy goal by withholding); a surface is "flagged" as the predict table says (its
    ``surface_extrapolates``: any press withheld by the gate or outside the family's domain; ``off_flagged_gate_off``
    counts those the family's own domain flags, the gate off; ``off_mostly_flagged`` those with most presses
    flagged). Reported: median |log error| (and ``_given``: over the surfaces predict gives a number, the gate on),
    surfaces off by more than x/÷1.25 and how many of them are flagged, the share of surfaces whose
    90 % surface interval holds the panel's value (and of presses, with their own interval). Goal: median
    <= 0.15 on each pad, and no surface off by more than x/÷1.25 unflagged. The issue's five gratings alone are a
    second row (the issue's table).
(b) **The paper's 14 on a kept-back seed.** The study's LOSO figure of the first screen: mean per-specimen RMSE
    (results_loso.csv, the paper's 14 only), combined. Goal: smooth <= 0.17, fingerprint <= 0.19 (today's law). The
    pooled RMSE of cv.csv is shown beside it.
(c) **Fingerprint pad, a shape left out** (held_out.csv, scheme "shape", combined): per held-out shape, the share of
    presses flagged, or the shape's |log bias|. Goal: flagged >= 80 % or |log bias| <= 0.1. The held-out RMSE and the
    training mean's are shown beside them: a family that flags every press passes this goal whatever it predicts.
(d) **One fingerprint press at 1 N.** A family that reads a surface from its presses together: presses.csv at one
    press; one that reads each press alone: its LOSO per-specimen RMSE at 1N (held_out.csv, scheme "specimen").
    Beside the training mean's. Goal: <= 0.25.

Nothing is cached in the repository: studies, reports and model files go to ``--work`` (default a temporary folder,
removed at the end unless ``--keep``), and ``ROUGHSENSE_CACHE_DIR`` is set there when unset. What is already in
``--work`` for the same set, seed and code (roughsense's source fingerprint names each folder) is reused.

Run: .venv/bin/python benchmarks/bench_issue46.py [--seeds 7 11] [--train paper|paper+grooves|LIST] [--jobs 2]
     [--models NAME ...] [--work DIR --keep] [--out figures.csv] [--surfaces surfaces.csv]
"""
from __future__ import annotations

import argparse
import hashlib
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from roughsense._util.fingerprint import code_fingerprint

DESIGN_SEEDS = (0, 1, 2)
JUDGING_SEEDS = (7, 11)
#: The issue's five gratings (its table), then their mirrors and two more: never trained on, never chosen on.
ISSUE_FIVE = ("rect:2.5:1:2", "rect:5:1:4", "rect:4:1:3", "rect:3:1:2", "rect:4:1:1")
KEPT_BACK = ISSUE_FIVE + ("rect:2.5:1:0.5", "rect:5:1:1", "rect:3:1:1", "rect:3.5:1:1", "rect:4.5:1:3.5")
#: The twin's training set name, and what it holds: the paper's 14 plus lands of 0.3 and 0.7 of each period 2-5 mm.
PAPER_GROOVES_NAME = "paper+grooves"
GROOVE_RECTS = tuple(f"rect:{p:g}:1:{round(share * p, 3):g}" for p in (2, 3, 4, 5) for share in (0.3, 0.7))
CONDITION = "combined"
SINGLE_PRESS_CONDITION = "1N"

MEDIAN_LOG_ERROR_BAR = 0.15
OFF_FACTOR = 1.25
LOSO_BARS = {"smooth": 0.17, "fingerprint": 0.19}
SHAPE_PAD, SHAPE_FLAGGED_SHARE, SHAPE_LOG_BIAS = "fingerprint", 0.8, 0.1
SINGLE_PRESS_PAD, SINGLE_PRESS_BAR = "fingerprint", 0.25


def spec_name(spec: str) -> str:
    """The specimen's name in a study folder (as ``sim/specimens.parse_specimen`` gives it)."""
    from roughsense.sim.specimens import parse_specimen

    return parse_specimen(spec).name


def paper_specimens() -> tuple[str, ...]:
    from roughsense.paper import PAPER_SPECIMENS

    return tuple(PAPER_SPECIMENS)


def seed_label(seed: int) -> str:
    return f"{seed} (design)" if seed in DESIGN_SEEDS else f"{seed} (judging)" if seed in JUDGING_SEEDS else str(seed)


# --------------------------------------------------------------------------- running the twin and the commands


class Runner:
    """Runs ``roughsense`` commands in fresh processes, each timed, in ``work`` (nothing in the repository)."""

    def __init__(self, work: Path, jobs: int):
        self.work, self.jobs = work, jobs
        self.timings: list[tuple[str, float]] = []
        self.not_measured: list[str] = []
        os.environ.setdefault("ROUGHSENSE_CACHE_DIR", str(work / "cache"))  # this process predicts too
        self.env = dict(os.environ)
        #: The code's fingerprint names every folder and file made here (studies, reports and models are named after
        #: their study), so a result of other code is never reused.
        self.code = code_fingerprint("roughsense.cli", data_packages=("roughsense.data.paper",))[:12]

    def run(self, label: str, *args: str, check: bool = True) -> subprocess.CompletedProcess:
        command = [sys.executable, "-m", "roughsense.cli", *args, "--jobs", str(self.jobs)]
        start = time.perf_counter()
        done = subprocess.run(command, env=self.env, capture_output=True, text=True)
        seconds = time.perf_counter() - start
        self.timings.append((label, seconds))
        print(f"  {label}: {seconds:.1f} s (exit {done.returncode})", flush=True)
        if check and done.returncode not in (0, 3):  # 3: predict withheld some rows
            raise SystemExit(f"{label} failed: {' '.join(command)}\n{done.stderr.strip()}")
        return done

    def simulate(self, specimens: str, seed: int, tag: str) -> Path:
        """The study folder of ``specimens`` at ``seed`` (reused when a complete one is there)."""
        slug = hashlib.sha256(specimens.encode()).hexdigest()[:8]
        folder = self.work / f"{tag}-{slug}-s{seed}-{self.code}"
        if (folder / "ratings.csv").is_file() and (folder / "manifest.csv").is_file():
            return folder
        self.run(f"simulate {tag} seed {seed}", "simulate", "--out", str(folder), "--seed", str(seed),
                 "--specimens", specimens)
        return folder

    def training_study(self, train: str, seed: int) -> Path:
        """The training study of ``train``: "paper" (the paper's 14), :data:`PAPER_GROOVES_NAME` (its explicit list
        where ``simulate`` does not take the name) or a comma-separated list."""
        listed = ",".join(paper_specimens()) if train == "paper" else train
        if train == PAPER_GROOVES_NAME:
            slug = hashlib.sha256(listed.encode()).hexdigest()[:8]
            folder = self.work / f"train-{slug}-s{seed}-{self.code}"
            if not (folder / "ratings.csv").is_file():
                done = self.run(f"simulate train seed {seed}", "simulate", "--out", str(folder), "--seed", str(seed),
                                "--specimens", listed, check=False)
                if done.returncode != 0:
                    listed = ",".join(paper_specimens() + GROOVE_RECTS)
                    print(f"  simulate does not take {PAPER_GROOVES_NAME!r} (exit {done.returncode}): its explicit "
                          f"list instead", flush=True)
                    return self.simulate(listed, seed, "train")
            return folder
        return self.simulate(listed, seed, "train")

    def study(self, folder: Path, seed: int, families) -> Path | None:
        """The study's report folder (reused where it holds every family); None, said in one line, where ``study``
        fails on the set."""
        report = self.work / f"report-{folder.name}"
        done = (report / "presses.csv").is_file() and set(families) <= set(
            pd.read_csv(report / "results_loso.csv")["model"])
        if not done:
            done = self.run(f"study seed {seed}", "study", "--study", str(folder), "--out", str(report), "--seed",
                            str(seed), "--permutations", "0", "--force", check=False)
            if done.returncode != 0:
                reason = (done.stderr.strip().splitlines() or ["no message"])[-1]
                self.not_measured.append(f"(b)-(d) seed {seed}: study failed: {reason}")
                print(f"  NOT MEASURED: {self.not_measured[-1]}", flush=True)
                return None
        return report

    def fit(self, folder: Path, family: str, pad: str, seed: int) -> Path | None:
        """The family's model file for ``pad`` (combined); None, said in one line, where ``fit`` refuses it."""
        model = self.work / f"model-{family}-{pad}-{folder.name}.json"
        if not model.is_file():
            done = self.run(f"fit {family} {pad} seed {seed}", "fit", "--study", str(folder), "--pad", pad,
                            "--condition", CONDITION, "--model", family, "--out", str(model), "--seed", str(seed),
                            "--force", check=False)
            if done.returncode != 0:
                reason = (done.stderr.strip().splitlines() or ["no message"])[-1]
                self.not_measured.append(f"(a) {family} {pad}, seed {seed}: fit refused: {reason}")
                print(f"  NOT MEASURED: {self.not_measured[-1]}", flush=True)
                return None
        return model


# --------------------------------------------------------------------------- (a) kept-back gratings


def predicted_table(model_path: Path, kept: Path, gate: bool) -> pd.DataFrame:
    """``predict --study`` of the kept-back study as numbers; without the contact-image gate when ``gate`` is off."""
    import roughsense as rs
    from roughsense.model.gate_file import KEY
    from roughsense.model.modelfile import load_model

    loaded = load_model(model_path)
    if not gate:
        loaded.training.pop(KEY, None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rs.predict(loaded, study=kept)


def surface_rows(gated: pd.DataFrame, raw: pd.DataFrame, panel: pd.Series, kept_names: dict) -> pd.DataFrame:
    """One row per kept-back surface: the model's reading (gate off), its flags as predict gives them (gate on)."""
    value = next(c for c in raw.columns if c.startswith("roughness_rel_"))
    rows = []
    for name, spec in kept_names.items():
        own, given = raw[raw["specimen"] == name], gated[gated["specimen"] == name]
        prediction = float(own[value].mean())
        low, high = _surface_interval(own)
        pressed = own.dropna(subset=["pi90_low", "pi90_high"]) if "pi90_low" in own else own.iloc[:0]
        flags = given["withheld"].astype(bool) | given["extrapolates"].astype(bool)
        target = float(panel[name])
        rows.append({"specimen": name, "spec": spec, "issue_five": spec in ISSUE_FIVE, "panel": target,
                     "prediction": prediction, "prediction_gated": float(given[value].mean()),
                     "log_error": float(np.log(prediction / target)),
                     "flagged": bool(given["surface_extrapolates"].astype(bool).any()
                                     if "surface_extrapolates" in given else flags.any()),
                     "flagged_gate_off": bool(own["surface_extrapolates"].astype(bool).any()
                                              if "surface_extrapolates" in own else own["extrapolates"].any()),
                     "withheld_share": float(given["withheld"].astype(bool).mean()),
                     "flagged_share": float(flags.mean()),
                     "covered": bool(low <= target <= high) if np.isfinite(low) else np.nan,
                     "press_covered": float(((pressed["pi90_low"] <= target) & (target <= pressed["pi90_high"])).mean())
                     if len(pressed) else np.nan})
    return pd.DataFrame(rows)


def _surface_interval(rows: pd.DataFrame) -> tuple[float, float]:
    if "surface_pi90_low" not in rows or rows["surface_pi90_low"].isna().all():
        return float("nan"), float("nan")
    return float(rows["surface_pi90_low"].dropna().iloc[0]), float(rows["surface_pi90_high"].dropna().iloc[0])


def kept_back_figures(surfaces: pd.DataFrame) -> dict:
    """Goal (a)'s figures of a group of surfaces."""
    error = surfaces["log_error"].abs()
    off = error > np.log(OFF_FACTOR)
    median = float(error.median())
    unflagged = int((off & ~surfaces["flagged"]).sum())
    return {"n_surfaces": len(surfaces), "median_abs_log_error": median,
            "median_abs_log_error_given": float(np.log(surfaces["prediction_gated"] / surfaces["panel"]).abs().median()),
            "off_1.25": int(off.sum()), "off_flagged": int((off & surfaces["flagged"]).sum()),
            "off_unflagged": unflagged, "off_mostly_flagged": int((off & (surfaces["flagged_share"] > 0.5)).sum()),
            "off_flagged_gate_off": int((off & surfaces["flagged_gate_off"]).sum()),
            "surface_coverage": float(surfaces["covered"].astype(float).mean()),
            "press_coverage": float(surfaces["press_covered"].mean()),
            "passes": bool(median <= MEDIAN_LOG_ERROR_BAR and unflagged == 0)}


# --------------------------------------------------------------------------- (b)-(d) from the study's tables


def loso_figures(report: Path, families, paper: tuple[str, ...]) -> list[dict]:
    results = pd.read_csv(report / "results_loso.csv")
    cv = pd.read_csv(report / "components.csv")
    rows = []
    for family in families:
        for pad, part in results[(results["model"] == family) & (results["condition"] == CONDITION)].groupby(
                "pad", sort=False):
            pooled = cv[(cv["model"] == family) & (cv["pad"] == pad) & (cv["condition"] == CONDITION)
                        & (cv["cv"] == "loso")]["cv_rmse"]
            rmse = float(part[part["specimen"].isin(paper)]["rmse"].mean())
            bar = LOSO_BARS.get(pad, np.nan)
            rows.append({"family": family, "pad": pad, "loso_rmse": rmse, "pooled_cv_rmse": float(pooled.iloc[0])
                         if len(pooled) else np.nan, "bar": bar, "passes": bool(rmse <= bar)})
    return rows


def shape_figures(report: Path, families) -> list[dict]:
    held = pd.read_csv(report / "held_out.csv")
    part = held[(held["scheme"] == "shape") & (held["condition"] == CONDITION) & held["model"].isin(families)]
    rows = []
    for row in part.itertuples(index=False):
        bias = float(getattr(row, f"log_bias_{row.held_out}", np.nan))
        flagged = float(row.flagged_share)
        good = (flagged >= SHAPE_FLAGGED_SHARE) or (abs(bias) <= SHAPE_LOG_BIAS)
        rows.append({"family": row.model, "pad": row.pad, "held_out": row.held_out, "flagged_share": flagged,
                     "log_bias": bias, "rmse": float(row.rmse), "null_rmse": float(row.null_rmse),
                     "passes": bool(good) if row.pad == SHAPE_PAD else np.nan})
    return rows


def single_press_figures(report: Path, families) -> list[dict]:
    from roughsense.model.registry import engine

    presses = pd.read_csv(report / "presses.csv")
    held = pd.read_csv(report / "held_out.csv")
    rows = []
    for family in families:
        if engine(family).reads_surfaces:
            row = presses[(presses["model"] == family) & (presses["pad"] == SINGLE_PRESS_PAD)
                          & (presses["condition"] == SINGLE_PRESS_CONDITION) & (presses["n_presses"] == 1)]
            source = "presses.csv, 1 press"
        else:
            row = held[(held["model"] == family) & (held["pad"] == SINGLE_PRESS_PAD) & (held["scheme"] == "specimen")
                       & (held["condition"] == SINGLE_PRESS_CONDITION)]
            source = "held_out.csv, LOSO (each press alone)"
        rmse = float(row["rmse"].iloc[0]) if len(row) else np.nan
        rows.append({"family": family, "pad": SINGLE_PRESS_PAD, "rmse": rmse,
                     "null_rmse": float(row["null_rmse"].iloc[0]) if len(row) else np.nan, "source": source,
                     "passes": bool(rmse <= SINGLE_PRESS_BAR)})
    return rows


# --------------------------------------------------------------------------- one seed, then the tables


def one_seed(runner: Runner, seed: int, train: str, families, train_seed: int | None = None
             ) -> tuple[pd.DataFrame, dict]:
    """Every figure of one seed: the kept-back surfaces (a) and the study's rows (b)-(d); the models of (a) are
    fitted on ``train_seed``'s twin where given (the issue's protocol: the built-in study's model), else on
    ``seed``'s."""
    import roughsense as rs
    from roughsense.analysis.dataset import perceived_roughness

    print(f"seed {seed_label(seed)}", flush=True)
    folder = runner.training_study(train, seed)
    fitted_on = folder if train_seed is None else runner.training_study(train, train_seed)
    trained = set(pd.read_csv(fitted_on / "specimens.csv")["specimen"].astype(str))
    leaked = [s for s in KEPT_BACK if spec_name(s) in trained]
    if leaked:
        raise SystemExit(f"the training set holds kept-back gratings: {', '.join(leaked)}")
    kept = runner.simulate(",".join(("R3", *KEPT_BACK)), seed, "kept")
    report = runner.study(folder, seed, families)
    panel = perceived_roughness(rs.read_study(kept)).set_index("specimen")["gmean"]
    kept_names = {spec_name(s): s for s in KEPT_BACK}
    pads = list(pd.read_csv(folder / "manifest.csv")["pad"].unique())
    frames = []
    for family in families:
        for pad in pads:
            model = runner.fit(fitted_on, family, pad, seed if train_seed is None else train_seed)
            if model is None:
                continue
            start = time.perf_counter()
            rows = surface_rows(predicted_table(model, kept, True), predicted_table(model, kept, False), panel,
                                kept_names)
            runner.timings.append((f"predict {family} {pad} seed {seed}", time.perf_counter() - start))
            rows.insert(0, "pad", pad)
            rows.insert(0, "family", family)
            rows.insert(0, "seed", seed)
            frames.append(rows)
    paper = paper_specimens()
    study_rows = {"b": [], "c": [], "d": []} if report is None else {
        "b": loso_figures(report, families, paper), "c": shape_figures(report, families),
        "d": single_press_figures(report, families)}
    return pd.concat(frames, ignore_index=True), study_rows


def verdict(value) -> str:
    return "" if value is None or (isinstance(value, float) and np.isnan(value)) else "PASS" if value else "FAIL"


def goal_a_table(surfaces: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for (family, pad), part in surfaces.groupby(["family", "pad"], sort=False):
        groups = [(str(seed_label(s)), "kept-back 10", part[part["seed"] == s]) for s in part["seed"].unique()]
        groups += [("all", "kept-back 10", part), ("all", "issue's five", part[part["issue_five"]])]
        for seeds, subset, group in groups:
            rows.append({"family": family, "pad": pad, "seeds": seeds, "gratings": subset, **kept_back_figures(group)})
    return pd.DataFrame(rows)


def print_table(title: str, frame: pd.DataFrame) -> None:
    shown = frame.copy()
    if "passes" in shown:
        shown["goal"] = [verdict(v) for v in shown.pop("passes")]
    print(f"\n{title}")
    print(shown.round(3).to_string(index=False))


def print_surfaces(surfaces: pd.DataFrame) -> None:
    """The issue's table: panel and each family x pad's reading (gate off), x or / the panel, flagged or not."""
    cells = surfaces.assign(cell=[f"{r.prediction:.2f} ({_factor(r.log_error)}){' F' if r.flagged else ''}"
                                  for r in surfaces.itertuples()])
    wide = cells.pivot_table(index=["spec", "seed", "panel"], columns=["family", "pad"], values="cell",
                             aggfunc="first", sort=False)
    wide.columns = [f"{family} {pad}" for family, pad in wide.columns]
    print("\nPer surface (mean over presses, the gate off; x/÷ the panel; F: flagged by predict, gate on)")
    print(wide.reset_index().round(2).to_string(index=False))


def _factor(log_error: float) -> str:
    return f"x{np.exp(log_error):.2f}" if log_error >= 0 else f"/{np.exp(-log_error):.2f}"


def report_all(surfaces: pd.DataFrame, study_rows: dict, seeds) -> pd.DataFrame:
    """Print one table per goal; return every figure in long form (the --out CSV)."""
    names = ", ".join(seed_label(s) for s in seeds)
    print_surfaces(surfaces)
    a = goal_a_table(surfaces)
    print_table(f"(a) Kept-back gratings, seeds {names}: median |log error| <= {MEDIAN_LOG_ERROR_BAR} and none off by "
                f"more than x/÷{OFF_FACTOR} unflagged (median_..._given: the surfaces predict gives a number)", a)
    tables = {"a": a}
    words = {"b": f"(b) The paper's 14, LOSO mean per-specimen RMSE ({CONDITION}); bars {LOSO_BARS}",
             "c": f"(c) A shape left out ({CONDITION}): flagged >= {SHAPE_FLAGGED_SHARE:.0%} or |log bias| <= "
                  f"{SHAPE_LOG_BIAS} (goal on the {SHAPE_PAD} pad)",
             "d": f"(d) One {SINGLE_PRESS_PAD} press at {SINGLE_PRESS_CONDITION}: RMSE <= {SINGLE_PRESS_BAR}"}
    for goal, title in words.items():
        frame = pd.DataFrame(study_rows[goal])
        if frame.empty:
            print(f"\n{title}: NOT MEASURED (the study failed)")
            continue
        tables[goal] = frame
        print_table(f"{title}; seeds {names}", frame)
    long = []
    for goal, frame in tables.items():
        keys = [c for c in ("family", "pad", "seeds", "gratings", "held_out", "source") if c in frame]
        for column in (c for c in frame.columns if c not in keys):
            part = frame[keys].copy()
            part.insert(0, "goal", goal)
            part["figure"], part["value"] = column, frame[column].to_numpy()
            long.append(part)
    return pd.concat(long, ignore_index=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=list(JUDGING_SEEDS))
    parser.add_argument("--train", default=PAPER_GROOVES_NAME,
                        help="training specimens: 'paper' (the paper's 14), a set name simulate takes, or a "
                             f"comma-separated list (default {PAPER_GROOVES_NAME}, else its explicit list)")
    parser.add_argument("--train-seed", type=int,
                        help="fit (a)'s models on this seed's twin (the issue's protocol: 0, the built-in study) "
                             "instead of each judged seed's")
    parser.add_argument("--models", nargs="+", help="families (default: every registered one)")
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--work", type=Path, help="folder for the studies, reports and models (default: temporary)")
    parser.add_argument("--keep", action="store_true", help="keep --work's contents")
    parser.add_argument("--out", type=Path, help="write every figure here (CSV, long form)")
    parser.add_argument("--surfaces", type=Path, help="write the kept-back surfaces here (CSV)")
    args = parser.parse_args()
    from roughsense.model.registry import names

    families = [f for f in names() if args.models is None or f in args.models]
    work = args.work or Path(tempfile.mkdtemp(prefix="bench-issue46-"))
    work.mkdir(parents=True, exist_ok=True)
    print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
          f"families {', '.join(families)}; training {args.train}"
          f"{'' if args.train_seed is None else f' on seed {seed_label(args.train_seed)}'}; "
          f"seeds {', '.join(map(seed_label, args.seeds))}; "
          f"kept back {', '.join(KEPT_BACK)}; work {work}", flush=True)
    print(f"design seeds {', '.join(map(str, DESIGN_SEEDS))} (anything may be chosen on them); judging seeds "
          f"{', '.join(map(str, JUDGING_SEEDS))} (never looked at while choosing)", flush=True)
    runner = Runner(work, args.jobs)
    start = time.perf_counter()
    try:
        results = [one_seed(runner, seed, args.train, families, args.train_seed) for seed in args.seeds]
    finally:
        if args.work is None and not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    surfaces = pd.concat([r[0] for r in results], ignore_index=True)
    study_rows = {g: [{"seeds": seed_label(s), **row} for s, r in zip(args.seeds, results) for row in r[1][g]]
                  for g in ("b", "c", "d")}
    figures = report_all(surfaces, study_rows, args.seeds)
    for line in runner.not_measured:
        print(f"NOT MEASURED {line}")
    print(f"\nwall {time.perf_counter() - start:.0f} s; stages: "
          + "; ".join(f"{label} {seconds:.0f} s" for label, seconds in runner.timings))
    if args.out:
        figures.to_csv(args.out, index=False)
    if args.surfaces:
        surfaces.to_csv(args.surfaces, index=False)


if __name__ == "__main__":
    main()
