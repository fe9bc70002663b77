"""``roughsense simulate``: the digital twin writes a study folder (see docs/simulator.md)."""
from __future__ import annotations

from pathlib import Path

import typer

from .._util.text import counted
from ..paper import PAPER_FORCES_N, PAPER_REPETITIONS, PAPER_SPECIMENS
from ._common import Jobs, number_option, parse_float_list, parse_name_list, progress
from ._defaults import DEFAULT_FINGERPRINT_PERIOD_MM, DEFAULT_RIDGE_HEIGHT_MM, PAD_NAMES

ORDER = 40
#: Number options are read by the one number parser (io.numbers): '1_0', non-ASCII digits and 'inf' are refused.
_PERIOD = number_option("--fingerprint-period-mm", quantity="ridge_period_mm", must="a positive number of mm from 0.001 to 100")
_SEED = number_option("--seed", quantity="seed")
_HEIGHT = number_option("--ridge-height-mm", low=0.0, low_open=True, must="a positive number of mm")


def simulate(
    out: Path = typer.Option(..., "--out", help="Study folder to write (must be new, empty or an interrupted "
                                                "simulation, unless --force)."),
    seed: int = typer.Option(0, "--seed", parser=_SEED, help="Master seed: the same seed gives byte-identical files."),
    pads: str = typer.Option(",".join(PAD_NAMES), "--pads", help="Pads: smooth, fingerprint (comma-separated)."),
    specimens: str = typer.Option(
        ",".join(PAPER_SPECIMENS), "--specimens", metavar="LIST", show_default=False,
        help="Comma-separated presets (R2..R5, C2..C5 in 0.5 mm steps) or specs of new specimens (syntax "
             "above). Default: the paper's 14, R2..R5 and C2..C5.",
    ),
    forces: str = typer.Option(",".join(f"{f:g}" for f in PAPER_FORCES_N), "--forces", help="Nominal pressing forces in N."),
    repetitions: int = typer.Option(PAPER_REPETITIONS, "--repetitions", parser=number_option("--repetitions", whole=True),
                                    help="Mounts per pad and specimen (each mount steps through the forces)."),
    fingerprint_period_mm: float = typer.Option(DEFAULT_FINGERPRINT_PERIOD_MM, "--fingerprint-period-mm", parser=_PERIOD,
                                                help="Ridge period of the fingerprint pad (paper: 1.0; human-sized: 0.5)."),
    ridge_height_mm: float = typer.Option(DEFAULT_RIDGE_HEIGHT_MM, "--ridge-height-mm", parser=_HEIGHT,
                                          help="Ridge height of the fingerprint pad (not in the paper)."),
    ratings_from: str = typer.Option(
        "paper", "--ratings-from",
        help="Where the panel's ratings come from: 'paper' (the paper's values for its presets, the simulated "
             "finger for any other specimen) or 'physics' (the simulated finger for every specimen).",
    ),
    stored_height_px: int = typer.Option(
        320, "--stored-height-px", parser=number_option("--stored-height-px", whole=True),
        help="Rows of each stored frame, centred on the 1080-row sensor (a sensor window holding the band; the "
             "paper's centred crop is unchanged); 0 stores whole frames."),
    jobs: Jobs = None,
    force: bool = typer.Option(
        False, "--force",
        help="Replace an earlier, complete simulated study as a whole (the new one is built beside it and swapped in; "
             "files you added to it are kept; a folder that is not a simulated study is refused). An interrupted "
             "simulation is replaced without it."),
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

    Example: --specimens R3,sin:3:0.5,rect:3.5:0.8
    """
    from .._util.lock import output_lock
    from ..sim import SimulationRun

    config = _config(pads=pads, specimens=specimens, forces=forces, repetitions=repetitions, seed=seed,
                     fingerprint_period_mm=fingerprint_period_mm, ridge_height_mm=ridge_height_mm,
                     ratings_from=ratings_from, stored_height_px=stored_height_px)
    with output_lock(out, command="simulate"):  # a second run into --out is refused, naming this one
        run = SimulationRun(out, config, force=force, jobs=jobs)
        for _ in progress(run, total=run.total, description="simulating"):
            pass
    typer.echo(f"wrote {counted(run.total, 'image')}, {counted(len(run.specimens), 'specimen')} and the panel's "
               f"ratings to {run.root}")


def _config(*, pads, specimens, forces, repetitions, seed, fingerprint_period_mm, ridge_height_mm, ratings_from,
            stored_height_px):
    """The simulator's settings from the command's text options (the simulator checks their values)."""
    from dataclasses import replace

    from ..sim import SimulationConfig
    from ..sim.optics import Camera

    return SimulationConfig(
        pads=tuple(parse_name_list(pads)), specimens=tuple(parse_name_list(specimens)),
        forces_n=tuple(parse_float_list(forces, name="forces")), repetitions=repetitions, seed=seed,
        fingerprint_period_mm=fingerprint_period_mm, ridge_height_mm=ridge_height_mm,
        ratings_from=ratings_from.strip().lower(), camera=replace(Camera(), stored_height_px=stored_height_px),
    )


def register(app: typer.Typer) -> None:
    app.command("simulate")(simulate)
