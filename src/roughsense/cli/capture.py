"""``roughsense capture``: run the paper's acquisition protocol on the bench (see docs/rig.md)."""
from __future__ import annotations

import sys
from pathlib import Path

import typer

from .. import defaults
from ..paper import PAPER_FORCES_N, PAPER_REPETITIONS
from ._common import number_option, parse_float_list

ORDER = 50
_REPETITIONS = number_option("--repetitions", whole=True)
_PX_PER_MM = number_option("--px-per-mm", quantity="px_per_mm")
_TIMEOUT_S = number_option("--timeout-s", low=0.0, low_open=True, high=3600.0)  # at most an hour
_WAVELENGTH = number_option("--wavelength-mm", quantity="wavelength_mm")
_DISCARD = number_option("--discard", low=0, high=1000, whole=True)


_SOURCE = typer.Option(
    ..., "--source", help="Camera index (0), device (/dev/video2), video file or image pattern (img_%04d.png).")
_OUT = typer.Option(..., "--out", "-o", help="Study folder: created on the first capture, extended by later runs.")
_REPETITIONS_OPTION = typer.Option(
    PAPER_REPETITIONS, "--repetitions", parser=_REPETITIONS,
    help="Target number of repetitions for this specimen and pad; a rerun captures only what is missing.")
_FORCE_INPUT = typer.Option(
    "manual", "--forces-from", help="'manual' (typed; Enter = nominal) or 'serial:PORT[:BAUD]' (a streaming scale).")
_PX_PER_MM_OPTION = typer.Option(
    None, "--px-per-mm", parser=_PX_PER_MM, help=f"Camera scale for a new study (default {defaults.PX_PER_MM:g}).")
_ROI = typer.Option(
    None, "--roi", help=f"Contact band for a new study: center, auto or X,Y,W,H (default {defaults.ROI}).")
_FORCES_N = typer.Option(None, "--forces-n", help="Protocol forces in N (default "
                         f"{','.join(f'{f:g}' for f in PAPER_FORCES_N)}, or the study's).")
_SHAPE = typer.Option(
    None, "--shape", help="Specimen shape for specimens.csv (rectangular, circular, sinusoidal, random, other).")
_MODEL = typer.Option(
    None, "--model", help="A model file (roughsense fit): each press is checked by its contact-image gate as it is "
    "taken, and one the model would withhold is named at once (kept; exit status 3 at the end).")
_DISCARD_OPTION = typer.Option(
    None, "--discard", parser=_DISCARD, help="Stale frames dropped before each capture (default 5 for cameras, 0 for files).")


def register(app: typer.Typer) -> None:
    @app.command("capture")
    def capture(
        source: str = _SOURCE,
        out: Path = _OUT,
        specimen: str = typer.Option(..., "--specimen", help="Specimen name, e.g. R3 (letters, digits, . _ -)."),
        pad: str = typer.Option(..., "--pad", help="Contact pad name, e.g. fingerprint or flat."),
        forces_n: str | None = _FORCES_N,
        repetitions: int = _REPETITIONS_OPTION,
        force_input: str = _FORCE_INPUT,
        px_per_mm: float | None = _PX_PER_MM_OPTION,
        roi: str | None = _ROI,
        timeout_s: float = typer.Option(5.0, "--timeout-s", parser=_TIMEOUT_S, help="Seconds to wait for a stable scale."),
        shape: str | None = _SHAPE,
        wavelength_mm: float | None = typer.Option(
            None, "--wavelength-mm", parser=_WAVELENGTH, help="Specimen surface wavelength for specimens.csv."),
        discard: int | None = _DISCARD_OPTION,
        model: Path | None = _MODEL,
    ) -> None:
        """Capture contact images with measured forces: for each repetition, one image at each force.

        The operator is prompted (on stderr) to set each force; the force is typed or read from the scale, a
        frame is grabbed and written, then its manifest row. Interrupt at any time: rerunning the same
        command resumes where it stopped, and nothing already captured is overwritten.
        """
        session = dict(specimen=specimen, pad=pad, repetitions=repetitions, px_per_mm=px_per_mm, roi=roi,
                       forces_n=parse_float_list(forces_n, name="forces-n") if forces_n is not None else None,
                       shape=shape, wavelength_mm=wavelength_mm)
        _run(out, source, force_input, timeout_s=timeout_s, discard=discard, session=session, model=model)


def _press_checker(model: Path | None):
    """The model's gate, one press at a time (None without --model); a bad model file is refused before the camera
    or the folder is touched."""
    if model is None:
        return None
    from ..model.modelfile import load_model
    from ..model.press_gate import press_checker

    return press_checker(load_model(model))


def _run(out: Path, source: str, force_input: str, *, timeout_s: float, discard: int | None, session: dict,
         model: Path | None = None) -> None:
    """Lock the folder, open the camera and the scale, capture, and say what was done."""
    from .._util.lock import output_lock
    from ..rig.camera import open_source
    from ..rig.capture import capture_session
    from ..rig.scale import open_force_input

    inspect = _press_checker(model)
    # The folder's lock first: a second capture is told who is capturing, before it opens the busy camera.
    with output_lock(out, command="capture") as lock, open_source(source, discard=discard) as frames, \
            open_force_input(force_input, timeout_s=timeout_s) as scale:
        try:
            result = capture_session(out, source=frames, force_input=scale, held=lock, inspect=inspect, **session)
        except KeyboardInterrupt:
            print(f"roughsense: capture interrupted; rerun the same command to resume into {out}", file=sys.stderr)
            raise
    specimen, pad = session["specimen"], session["pad"]
    done = f"{result.already_done} step(s) were already captured; " if result.already_done else ""
    typer.echo(f"{done}captured {len(result.captured)} image(s) of {specimen}/{pad} into {out}")
    if result.specimen_incomplete:
        typer.echo(f"note: fill in shape and wavelength_mm for {specimen} in {out / 'specimens.csv'} before the analysis "
                   "(or rerun with --shape and --wavelength-mm)")
    if result.default_scale:
        _warn_default_scale(out)
    _check_scale(out, pad)
    _exit_if_suspect(result.suspect, model)


def _exit_if_suspect(suspect: list[tuple[str, str]], model: Path | None) -> None:
    """One line per press the model's gate would withhold, and exit status 3 (``_common.WITHHELD_EXIT``)."""
    from ._common import WITHHELD_EXIT

    if not suspect:
        return
    for image, why in suspect:
        typer.echo(f"roughsense: {image}: {why}", err=True)
    typer.echo(f"roughsense: {len(suspect)} press(es) are no contact image {model} would read (kept in the study; "
               f"retake or remove them); exit status {WITHHELD_EXIT}", err=True)
    raise typer.Exit(WITHHELD_EXIT)


def _warn_default_scale(out: Path) -> None:
    """A new study.toml with the paper's camera scale, not this rig's: every spectrum is in mm^-1 and depends on it."""
    import warnings

    from ..errors import RoughsenseWarning
    from ..io.study import STUDY_TOML

    warnings.warn(RoughsenseWarning(
        f"{out / STUDY_TOML} states px_per_mm = {defaults.PX_PER_MM:g}, the paper's camera, not measured on this rig: "
        f"capture a target of known period (the reference R3) and run `roughsense calibrate {out}`, or pass "
        "--px-per-mm"), stacklevel=2)


def _check_scale(out: Path, pad: str) -> None:
    """The folder's stated scale against the pad's ridges and the reference specimen captured so far: one line (a
    warning when it is off: the stated px/mm is the user's, so it is measured with calibrate, never replaced here).
    The rig knows nothing of the sensor: the command composes them."""
    import warnings

    from ..errors import RoughsenseError, RoughsenseWarning
    from ..io.study import read_study
    from ..model.scale_check import UNCONFIRMED, check_study_scale

    try:
        check = check_study_scale(read_study(out), pad=pad)
    except RoughsenseError as exc:  # a folder not yet readable as a study (a specimen without its wavelength)
        typer.echo(f"roughsense: {UNCONFIRMED}: {exc}", err=True)
        return
    if check.off:
        warnings.warn(RoughsenseWarning(f"{check.summary()}; measure it with `roughsense calibrate {out}`"),
                      stacklevel=2)
    else:
        typer.echo(f"roughsense: {check.summary()}", err=True)
