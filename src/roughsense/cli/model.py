"""``roughsense fit`` and ``roughsense predict``: a PLS1 model from a study, and roughness from images."""
from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import ConfigError
from ._common import check_seed, progress
from ._studies import STUDY_METAVAR, resolve_study

ORDER = 20

CONDITIONS = ("1N", "2N", "3N", "combined")


def _parse_cv(text: str):
    """'loo' | 'loso' | K (shuffled K-fold) -> (label, cv argument for pls_cv)."""
    value = text.strip().lower()
    if value in ("loo", "loso"):
        return value
    try:
        k = int(value)
    except ValueError:
        raise ConfigError(f"--cv must be loo, loso or a number of folds, got {text!r}") from None
    if k < 2:
        raise ConfigError(f"--cv K-fold needs K >= 2, got {k}")
    return k


def _curve_table(result, chosen: int):
    import pandas as pd

    marks = []
    for k in range(result.rmse.size):
        tags = []
        if k == result.best_n_components:
            tags.append("min")
        if k == result.one_se_n_components:
            tags.append("1-SE")
        if k == chosen:
            tags.append("chosen")
        marks.append(", ".join(tags))
    return pd.DataFrame(
        {"components": range(result.rmse.size), "rmse": result.rmse, "rmse_se": result.rmse_se, "note": marks}
    )


def register(app: typer.Typer) -> None:
    @app.command("fit")
    def fit(
        study: Annotated[str, typer.Option(
            "--study", metavar=STUDY_METAVAR,
            help="Study folder with images, manifest and ratings, or builtin: the simulated paper study of --seed.",
        )],
        pad: Annotated[str, typer.Option("--pad", help="Which pad's images to use (a value of the manifest's pad column).")],
        condition: Annotated[
            str, typer.Option("--condition", help="Force condition: 1N, 2N, 3N, or combined (a trial's three spectra side by side).")
        ],
        out: Annotated[Path, typer.Option("--out", "-o", help="Model file to write (JSON).")],
        max_components: Annotated[
            int | None,
            typer.Option(
                "--max-components",
                help="Largest number of PLS components to cross-validate. Default: 20, or fewer if the data support fewer.",
                show_default=False,
            ),
        ] = None,
        cv: Annotated[
            str,
            typer.Option("--cv", help="Cross-validation: loo (the paper's leave-one-out), loso (leave one specimen out) or K (shuffled K-fold)."),
        ] = "loo",
        rule: Annotated[
            str, typer.Option("--rule", help="Component choice: min (lowest CV RMSE, the paper's rule) or 1se (fewest within one SE of it).")
        ] = "min",
        seed: Annotated[int, typer.Option("--seed", help="Seed for the K-fold shuffle (LOO and LOSO use no randomness) and of --study builtin.")] = 0,
        jobs: Annotated[int, typer.Option("--jobs", "-j", help="Image decoding threads; -1 uses every core.")] = -1,
        force: Annotated[bool, typer.Option("--force", help="Replace MODEL.json if it exists.")] = False,
    ) -> None:
        """Fit the paper's PLS1 model (SIMPLS, X centred) for one pad and force condition.

        Spectra are computed from the study's images with its camera scale and ROI; the response is each
        specimen's perceived roughness (geometric mean over participants). The number of components is
        chosen by cross-validation; the CV curve is printed and stored in the model file with the feature
        definition, so `roughsense predict` recomputes features exactly as here.
        """
        import dataclasses

        import numpy as np

        from .. import dataset
        from ..atomic import check_can_write
        from ..errors import InputError
        from ..modelfile import feature_definition_for, save_model
        from ..pls import SIMPLS, pls_cv
        from ..study import MANIFEST_CSV, RATINGS_CSV, read_study

        if condition not in CONDITIONS:
            raise ConfigError(f"--condition must be one of {', '.join(CONDITIONS)}, got {condition!r}")
        if rule not in ("min", "1se"):
            raise ConfigError(f"--rule must be min or 1se, got {rule!r}")
        scheme = _parse_cv(cv)
        check_seed(seed)
        if max_components is not None and max_components < 1:
            raise ConfigError(f"--max-components must be at least 1, got {max_components}")
        check_can_write(out, force=force)

        study = resolve_study(study, seed=seed, jobs=None if jobs < 1 else jobs)
        loaded = read_study(study, require_ratings=True)
        manifest_path = loaded.root / MANIFEST_CSV
        if pad not in loaded.pads:
            raise InputError(f"no images of pad {pad!r} (pads in the study: {', '.join(loaded.pads)})", path=manifest_path)
        # Only this pad's images at the forces the model uses need spectra.
        needed = loaded.manifest["pad"].eq(pad) & loaded.manifest["condition"].isin(dataset.conditions_of(condition))
        if not needed.any():
            present = sorted(set(loaded.manifest.loc[loaded.manifest["pad"].eq(pad), "condition"]))
            raise InputError(
                f"no images of pad {pad!r} at {condition} (conditions present: {', '.join(present)})", path=manifest_path
            )
        subset = dataclasses.replace(loaded, manifest=loaded.manifest[needed].reset_index(drop=True))
        features = dataset.study_features(subset, n_jobs=jobs, progress=progress)
        X, meta = dataset.condition_matrix(features, pad, condition, source=manifest_path)
        y = dataset.targets(meta, dataset.perceived_roughness(loaded), path=loaded.root / RATINGS_CSV)
        groups = meta["specimen"].to_numpy() if scheme == "loso" else None
        n = len(y)
        if scheme == "loo":
            largest_fold = 1
        elif scheme == "loso":
            largest_fold = int(meta["specimen"].value_counts().max())
        else:
            largest_fold = -(-n // scheme)
        supported = min(n - largest_fold - 1, X.shape[1])
        if supported < 1:
            raise ConfigError(f"too few samples ({n}) for {cv} cross-validation of pad {pad!r} at {condition}")
        k_max = min(20, supported) if max_components is None else max_components
        result = pls_cv(
            X, y, max_components=k_max,
            cv=None if scheme == "loso" else scheme, groups=groups, random_state=np.random.default_rng(seed),
            cap=max_components is None,  # the default 20 is an upper bound; a user's explicit count is not
        )
        k_max = result.max_components
        chosen = result.best_n_components if rule == "min" else result.one_se_n_components
        model = SIMPLS(n_components=chosen).fit(X, y)

        conditions = dataset.conditions_of(condition)
        definition = feature_definition_for(dataset.spectrum_for(loaded), conditions)
        training = {
            "study": loaded.name,
            "study_path": str(study),
            "pad": pad,
            "condition": condition,
            "n_samples": int(n),
            "specimens": sorted(map(str, meta["specimen"].unique())),
            "reference_specimen": loaded.reference_specimen,
            "cv": scheme if isinstance(scheme, str) else f"{scheme}-fold",
            "seed": int(seed),
            "rule": rule,
            "max_components": int(k_max),
            "cv_rmse": [float(v) for v in result.rmse],
            "cv_rmse_se": [float(v) for v in result.rmse_se],
            "best_n_components": int(result.best_n_components),
            "one_se_n_components": int(result.one_se_n_components),
            "n_components": int(chosen),
        }
        save_model(out, model, feature_definition=definition, training=training, force=force)

        table = _curve_table(result, chosen)
        typer.echo(f"{loaded.name}: pad {pad}, {condition}, {n} samples x {X.shape[1]} features, {result.scheme} CV")
        typer.echo(table.to_string(index=False, float_format=lambda v: f"{v:.5f}"))
        typer.echo(
            f"chosen: {chosen} components (CV RMSE {result.rmse[chosen]:.5f}; min at {result.best_n_components}, "
            f"one-SE rule {result.one_se_n_components})"
        )
        typer.echo(f"wrote {out}")

    @app.command("predict", context_settings={"ignore_unknown_options": True})
    def predict(
        model: Annotated[Path, typer.Argument(metavar="MODEL.json", help="A model file written by `roughsense fit`.")],
        images: Annotated[
            list[str] | None,
            typer.Argument(
                metavar="[IMAGE...] [--images-1n IMAGE... --images-2n IMAGE... --images-3n IMAGE...]",
                help="Contact images. A single-force model scores each image. A combined model needs each image's "
                     "force: give one --images-XN flag per force of the model, each followed by its images; the i-th "
                     "image of each flag form one trial (or use --study).",
                show_default=False,
            ),
        ] = None,
        study: Annotated[str | None, typer.Option("--study", metavar=STUDY_METAVAR, help="Score a study's images, grouped into trials by its manifest (the model's pad and forces); builtin: the simulated paper study of --seed.")] = None,
        seed: Annotated[int, typer.Option("--seed", help="Seed of --study builtin.")] = 0,
        specimens: Annotated[list[str] | None, typer.Option("--specimen", help="With --study: only this specimen (repeat for more).")] = None,
        out: Annotated[Path | None, typer.Option("--out", "-o", help="CSV to write (one row per trial: images, pad, condition, roughness). Default: print a table.")] = None,
        jobs: Annotated[int, typer.Option("--jobs", "-j", help="Image decoding threads; -1 uses every core.")] = 1,
        force: Annotated[bool, typer.Option("--force", help="Replace PRED.csv if it exists.")] = False,
        source: Annotated[str | None, typer.Option("--source", help="With --live: a camera index, video file or image-sequence pattern (anything OpenCV's VideoCapture opens).")] = None,
        live: Annotated[bool, typer.Option("--live", help="Score frames from --source continuously and show the predicted roughness on the terminal (Ctrl-C stops).")] = False,
        max_frames: Annotated[int | None, typer.Option("--max-frames", min=1, help="With --live: stop after this many scored frames.")] = None,
    ) -> None:
        """Predict perceived roughness from contact images with a fitted model.

        Features are recomputed with the model's own definition (camera scale, ROI, band, frequencies).
        A combined model scores trials: group their images with --study DIR [--specimen S] (from the manifest) or
        with --images-1n ... --images-2n ... --images-3n ...; an image whose name says another force than its
        slot (e.g. _1N_ in the 2N slot) is refused. With --live --source SRC, a single-force model scores camera
        frames continuously.
        """
        from ..atomic import check_can_write, write_csv
        from ..modelfile import load_model
        from ..scoring import model_condition, model_pad, score_images

        positional, by_condition = _split_image_flags(images or [])
        given = [name for name, used in (("IMAGE...", positional), ("--images-XN", by_condition),
                                         ("--study", study is not None)) if used]
        if live or source is not None:
            if not (live and source is not None):
                raise ConfigError("live scoring needs both --live and --source SRC")
            if given:
                raise ConfigError(f"give either {given[0]} or --live --source SRC, not both")
            _predict_live(load_model(model), source, max_frames)
            return
        if not given:
            raise ConfigError("no images given: pass IMAGE..., --images-1n ... (one flag per force) or --study DIR "
                              "(or --live --source SRC)")
        if len(given) > 1:
            raise ConfigError(f"give images one way: {given[0]} or {given[1]}, not both")
        if specimens and study is None:
            raise ConfigError("--specimen selects from a study: add --study DIR")
        if out is not None:
            check_can_write(out, force=force)
        loaded = load_model(model)
        if study is not None:
            study = resolve_study(study, seed=seed, jobs=None if jobs < 1 else jobs)
        trials, table = _trials(loaded, positional, by_condition, study, specimens or [])
        roughness = score_images(loaded, [image for trial in trials for image in trial], n_jobs=jobs,
                                 progress=progress)
        if len(loaded.conditions) == 1:
            table["image"] = [str(t[0]) for t in trials]
        else:
            for i, condition in enumerate(loaded.conditions):
                table[f"image_{condition}"] = [str(t[i]) for t in trials]
        table["pad"] = model_pad(loaded)
        table["condition"] = model_condition(loaded)
        table["roughness"] = roughness
        if out is None:
            typer.echo(table.to_string(index=False, float_format=lambda v: f"{v:.6g}"))
        else:
            write_csv(out, table, float_format="%.17g")
            typer.echo(f"wrote {len(table)} prediction(s) to {out}")


_IMAGE_FLAG = "--images-"


def _split_image_flags(tokens: list[str]) -> tuple[list[Path], dict[str, list[Path]]]:
    """Bare images, and the images after each ``--images-XN`` flag (up to the next flag), by condition "XN".

    Click cannot give an option several values, so the command takes every token as an argument and splits here;
    any other unknown ``--option`` is refused rather than taken for a file.
    """
    positional: list[Path] = []
    by_condition: dict[str, list[Path]] = {}
    current: list[Path] | None = None
    for token in tokens:
        if token.startswith(_IMAGE_FLAG):
            label, _, first = token[len(_IMAGE_FLAG):].partition("=")
            condition = label.upper()
            try:
                valid = condition.endswith("N") and float(condition[:-1]) > 0
            except ValueError:
                valid = False
            if not valid:
                raise ConfigError(f"{token.partition('=')[0]}: expected a force like --images-1n or --images-2.5n")
            condition = f"{float(condition[:-1]):g}N"
            current = by_condition.setdefault(condition, [])
            if first:
                current.append(Path(first))
        elif token.startswith("-") and len(token) > 1 and not Path(token).exists():
            raise ConfigError(f"no such option: {token}")
        elif current is not None:
            current.append(Path(token))
        else:
            positional.append(Path(token))
    return positional, by_condition


def _trials(loaded, positional, by_condition, study, specimens):
    """The model's trials (tuples of images in its condition order) and the table's leading columns."""
    import pandas as pd

    from ..scoring import groups_from_flags, groups_from_images, groups_from_study

    if study is not None:
        from ..study import read_study

        groups, meta = groups_from_study(loaded, read_study(study), specimens)
        return groups, meta
    groups = groups_from_flags(loaded, by_condition) if by_condition else groups_from_images(loaded, positional)
    return groups, pd.DataFrame(index=range(len(groups)))


def _predict_live(loaded, source: str, max_frames: int | None) -> None:
    """Wire the model's scorer into the rig's live loop (the rig itself knows nothing of models)."""
    from ..rig.live import live_scores, render_live
    from ..scoring import model_spectrum

    if len(loaded.conditions) != 1:
        raise ConfigError(
            f"live scoring needs a single-force model; this one combines {', '.join(loaded.conditions)} "
            "(fit one with --condition 1N, 2N or 3N)"
        )
    spectrum = model_spectrum(loaded)
    plan = spectrum._plan()

    def score_frame(rgb):
        return float(loaded.predict(plan.spectrum(rgb)[None, :])[0])

    summary = render_live(live_scores(source, score_frame, max_frames=max_frames))
    last = "none" if summary.last_score is None else f"{summary.last_score:.4f}"
    typer.echo(f"{summary.updates} update(s), {summary.updates_per_s:.1f}/s; last roughness {last}")
