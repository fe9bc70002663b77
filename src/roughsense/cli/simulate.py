"""``roughsense simulate``: the digital twin writes a study folder (see docs/simulator.md)."""
from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .. import defaults
from .._util.text import counted
from ..paper import FINGERPRINT_PAD, PAPER_FORCES_N, PAPER_REPETITIONS, PAPER_SPECIMENS, SMOOTH_PAD
from ._common import Jobs, number_option, parse_float_list, parse_name_list, progress

ORDER = 40
#: Number options are read by the one number parser (io.numbers): '1_0', non-ASCII digits and 'inf' are refused.
_PERIOD = number_option("--fingerprint-period-mm", quantity="ridge_period_mm", must="a positive number of mm from 0.001 to 100")
_SEED = number_option("--seed", quantity="seed")
_HEIGHT = number_option("--ridge-height-mm", low=0.0, low_open=True, must="a positive number of mm")

# The command's options, declared once here so that the command itself reads as what it does.
Out = Annotated[Path, typer.Option("--out", "-o", help="Study folder to write (must be new, empty or an interrupted "
                                                 "simulation, unless --force).")]
Seed = Annotated[int, typer.Option("--seed", parser=_SEED,
                                   help="Master seed: the same seed gives byte-identical files.")]
Pads = Annotated[str, typer.Option("--pads", help="Pads: smooth, fingerprint (comma-separated).")]
Specimens = Annotated[str, typer.Option(
    "--specimens", metavar="LIST", show_default=False,
    help="Comma-separated presets (R2..R5, C2..C5 in 0.5 mm steps), specs of new specimens (syntax "
         "above) or named sets: paper (the paper's 14), paper+grooves (the 14 and 8 rectangles whose land is 0.3 or "
         "0.7 of the period 2, 3, 4 or 5 mm: groove width apart from period), rectangular, circular. Default: the "
         "paper's 14, R2..R5 and C2..C5.")]
ForcesN = Annotated[str, typer.Option("--forces-n", help="Nominal pressing forces in N (comma-separated).")]
Repetitions = Annotated[int, typer.Option(
    "--repetitions", parser=number_option("--repetitions", whole=True),
    help="Mounts per pad and specimen (each mount steps through the forces).")]
Period = Annotated[float, typer.Option("--fingerprint-period-mm", parser=_PERIOD,
                                       help="Ridge period of the fingerprint pad (paper: 1.0; human-sized: 0.5).")]
RidgeHeight = Annotated[float, typer.Option("--ridge-height-mm", parser=_HEIGHT,
                                            help="Ridge height of the fingerprint pad (not in the paper).")]
RatingsFrom = Annotated[str, typer.Option(
    "--ratings-from",
    help="Where the panel's ratings come from: 'paper' (the paper's values for its presets, the simulated "
         "finger for any other specimen) or 'physics' (the simulated finger for every specimen).")]
StoredHeight = Annotated[int, typer.Option(
    "--stored-height-px", parser=number_option("--stored-height-px", whole=True),
    help="Rows of each stored frame, centred on the 1080-row sensor (a sensor window holding the band; the "
         "paper's centred crop is unchanged); 0 stores whole frames.")]
Force = Annotated[bool, typer.Option(
    "--force",
    help="Replace an earlier, complete simulated study as a whole (the new one is built beside it and swapped in; "
         "files you added to it are kept; a folder that is not a simulated study is refused). An interrupted "
         "simulation is replaced without it.")]


def simulate(
    out: Out, seed: Seed = defaults.SEED, pads: Pads = f"{SMOOTH_PAD},{FINGERPRINT_PAD}",
    specimens: Specimens = ",".join(PAPER_SPECIMENS), forces_n: ForcesN = ",".join(f"{f:g}" for f in PAPER_FORCES_N),
    repetitions: Repetitions = PAPER_REPETITIONS, fingerprint_period_mm: Period = defaults.FINGERPRINT_PERIOD_MM,
    ridge_height_mm: RidgeHeight = defaults.RIDGE_HEIGHT_MM, ratings_from: RatingsFrom = defaults.RATINGS_FROM,
    stored_height_px: StoredHeight = defaults.STORED_HEIGHT_PX, jobs: Jobs = None, force: Force = False,
) -> None:
    """Simulate the paper's experiment (rig, specimens, pads and participants) and write a study folder.

    The defaults are the paper's full study: 2 pads x 14 specimens x 3 forces x 10 repetitions = 840 images,
    and 10 participants x 3 sessions x 13 specimens = 390 ratings (R3 is the reference). Try a new pad or
    specimen before building it, e.g. --fingerprint-period-mm 0.5 or --specimens R3,sin:3:0.5.

    Specs of new specimens for --specimens, all lengths in mm (brackets mark optional parts):

    - rect:WAVELENGTH[:DEPTH[:RIDGE_WIDTH]]: rectangular grating
    - circ:DIAMETER: touching semi-cylinders
    - sin:WAVELENGTH:AMPLITUDE: sinusoid
    - rand:CORRELATION_LENGTH:RMS[:SEED]: random rough surface

    Example: --specimens R3,sin:3:0.5,rect:3.5:0.8 or --specimens paper+grooves
    """
    from .._util.lock import output_lock
    from ..sim import SimulationRun

    config = _config(pads=pads, specimens=specimens, forces_n=forces_n, repetitions=repetitions, seed=seed,
                     fingerprint_period_mm=fingerprint_period_mm, ridge_height_mm=ridge_height_mm,
                     ratings_from=ratings_from, stored_height_px=stored_height_px)
    with output_lock(out, command="simulate"):  # a second run into --out is refused, naming this one
        run = SimulationRun(out, config, force=force, jobs=jobs)
        for _ in progress(run, total=run.total, description="simulating"):
            pass
    typer.echo(f"wrote {counted(run.total, 'image')}, {counted(len(run.specimens), 'specimen')} and the panel's "
               f"ratings to {run.root}")


def _config(*, pads, specimens, forces_n, repetitions, seed, fingerprint_period_mm, ridge_height_mm, ratings_from,
            stored_height_px):
    """The simulator's settings from the command's text options (the simulator checks their values)."""
    from dataclasses import replace

    from ..sim import SimulationConfig
    from ..sim.optics import Camera

    return SimulationConfig(
        pads=tuple(parse_name_list(pads)), specimens=tuple(parse_name_list(specimens)),
        forces_n=tuple(parse_float_list(forces_n, name="forces-n")), repetitions=repetitions, seed=seed,
        fingerprint_period_mm=fingerprint_period_mm, ridge_height_mm=ridge_height_mm,
        ratings_from=ratings_from.strip().lower(), camera=replace(Camera(), stored_height_px=stored_height_px),
    )


def register(app: typer.Typer) -> None:
    app.command("simulate")(simulate)
