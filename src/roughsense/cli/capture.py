"""``roughsense capture``: run the paper's acquisition protocol on the bench (see docs/rig.md)."""
from __future__ import annotations

import sys
from pathlib import Path

import typer

from ..paper import PAPER_REPETITIONS
from ._common import number_option, parse_float_list
from ._defaults import DEFAULT_PX_PER_MM

ORDER = 50
_REPETITIONS = number_option("--repetitions", whole=True)
_PX_PER_MM = number_option("--px-per-mm", quantity="px_per_mm")
_TIMEOUT_S = number_option("--timeout-s", low=0.0, low_open=True, high=3600.0)  # at most an hour
_WAVELENGTH = number_option("--wavelength-mm", quantity="wavelength_mm")
_DISCARD = number_option("--discard", low=0, high=1000, whole=True)


def register(app: typer.Typer) -> None:
    @app.command("capture")
    def capture(
        source: str = typer.Option(
            ..., "--source",
            help="Camera index (0), device (/dev/video2), video file or image pattern (img_%04d.png)."),
        out: Path = typer.Option(..., "--out", help="Study folder: created on the first capture, extended by later runs."),
        specimen: str = typer.Option(..., "--specimen", help="Specimen name, e.g. R3 (letters, digits, . _ -)."),
        pad: str = typer.Option(..., "--pad", help="Contact pad name, e.g. fingerprint or flat."),
        forces: str | None = typer.Option(None, "--forces", help="Protocol forces in N (default 1,2,3, or the study's)."),
        repetitions: int = typer.Option(
            PAPER_REPETITIONS, "--repetitions", parser=_REPETITIONS,
            help="Target number of repetitions for this specimen and pad; a rerun captures only what is missing."),
        force_input: str = typer.Option(
            "manual", "--force-input",
            help="'manual' (typed; Enter = nominal) or 'serial:PORT[:BAUD]' (a streaming scale)."),
        px_per_mm: float | None = typer.Option(
            None, "--px-per-mm", parser=_PX_PER_MM, help=f"Camera scale for a new study (default {DEFAULT_PX_PER_MM:g})."),
        roi: str | None = typer.Option(
            None, "--roi",
            help="Contact band for a new study: center, auto or X,Y,W,H (default center)."),
        timeout_s: float = typer.Option(5.0, "--timeout-s", parser=_TIMEOUT_S, help="Seconds to wait for a stable scale."),
        shape: str | None = typer.Option(
            None, "--shape",
            help="Specimen shape for specimens.csv (rectangular, circular, sinusoidal, random, other)."),
        wavelength_mm: float | None = typer.Option(
            None, "--wavelength-mm", parser=_WAVELENGTH,
            help="Specimen surface wavelength for specimens.csv."),
        discard: int | None = typer.Option(
            None, "--discard", parser=_DISCARD,
            help="Stale frames dropped before each capture (default 5 for cameras, 0 for files)."),
    ) -> None:
        """Capture contact images with measured forces: for each repetition, one image at each force.

        The operator is prompted (on stderr) to set each force; the force is typed or read from the scale, a
        frame is grabbed and written, then its manifest row. Interrupt at any time: rerunning the same
        command resumes where it stopped, and nothing already captured is overwritten.
        """
        from .._util.lock import output_lock
        from ..rig.camera import open_source
        from ..rig.capture import capture_session
        from ..rig.scale import open_force_input

        force_list = parse_float_list(forces, name="forces") if forces is not None else None
        # The folder's lock first: a second capture is told who is capturing, before it opens the busy camera.
        with output_lock(out, command="capture"), open_source(source, discard=discard) as frames, \
                open_force_input(force_input, timeout_s=timeout_s) as scale:
            try:
                result = capture_session(
                    out, source=frames, force_input=scale, specimen=specimen, pad=pad, repetitions=repetitions,
                    forces_n=force_list, px_per_mm=px_per_mm, roi=roi, shape=shape, wavelength_mm=wavelength_mm,
                )
            except KeyboardInterrupt:
                print(f"roughsense: capture interrupted; rerun the same command to resume into {out}", file=sys.stderr)
                raise
        done = f"{result.already_done} step(s) were already captured; " if result.already_done else ""
        typer.echo(f"{done}captured {len(result.captured)} image(s) of {specimen}/{pad} into {out}")
        if result.specimen_incomplete:
            typer.echo(f"note: fill in shape and wavelength_mm for {specimen} in {out / 'specimens.csv'} before the analysis "
                       "(or rerun with --shape and --wavelength-mm)")
