"""``roughsense ratings`` (summarise magnitude estimates) and ``roughsense protocol`` (draw the orders)."""
from __future__ import annotations

import warnings
from pathlib import Path
from typing import Annotated

import typer

from .. import defaults
from .._util.text import counted
from ..errors import ConfigError, RoughsenseWarning
from ..paper import PAPER_PARTICIPANTS, PAPER_SESSIONS, PAPER_SPECIMENS, REFERENCE_SPECIMEN
from ._common import check_seed, number_option, parse_name_list

_SEED = number_option("--seed", quantity="seed")
_PARTICIPANTS = number_option("--participants", low=1, whole=True)
_SESSIONS = number_option("--sessions", low=1, whole=True)

ORDER = 30


def _specimen_names(value: str) -> list[str]:
    """A comma list (a set of the twin's, e.g. paper+grooves, stands for its specimens' names), or a study's
    specimens.csv (its ``specimen`` column, in file order)."""
    from ..io.names import check_name
    from ..io.study import read_specimens
    from ..sim.specimens import SPECIMEN_SETS, expand_specimen_sets, parse_specimen

    path = Path(value)
    if value.lower().endswith(".csv") or path.is_file():
        return list(read_specimens(path)["specimen"])
    names = parse_name_list(value)
    if not names:
        raise ConfigError("--specimens: no names given")
    if any(name.lower() in SPECIMEN_SETS for name in names):
        names = [parse_specimen(text).name for text in expand_specimen_sets(names)]
    return [check_name(name, what="--specimens: specimen") for name in names]


def _print_summary(summary, reference: str) -> None:
    import math

    from rich.console import Console
    from rich.table import Table

    from ..analysis.magnitude_estimation import SD_DEFINITION

    table = Table(title="Perceived roughness (magnitude estimation)")
    table.add_column("specimen")
    for name in ("gmean", "sd", "participants", "sessions"):
        table.add_column(name, justify="right")
    for row in summary.itertuples(index=False):
        sd = "—" if math.isnan(row.sd) else f"{row.sd:.3f}"
        if row.specimen == reference:
            table.add_row(row.specimen, "1.000", sd, "reference", "—")
        else:
            table.add_row(row.specimen, f"{row.gmean:.3f}", sd, str(row.n_participants), str(row.n_sessions))
    console = Console()
    console.print(table)
    console.print(SD_DEFINITION, soft_wrap=True, highlight=False)


RatingsFile = Annotated[Path, typer.Argument(
    metavar="RATINGS", show_default=False,
    help="ratings.csv (participant, session, specimen, rating), a filled-in schedule CSV, "
         "or a filled-in Markdown sheet (.md). Blank rating cells are trials not done.")]
SummaryOut = Annotated[Path, typer.Option(
    "--out", "-o", help="Summary CSV: specimen, gmean, sd, n_participants, n_sessions.")]
RatingsSpecimens = Annotated[str | None, typer.Option(
    "--specimens", show_default=False,
    help="A study's specimens.csv (or a comma list): refuse unknown specimens and order the rows.")]


def ratings(
    ratings_file: RatingsFile, out: SummaryOut,
    reference: Annotated[str, typer.Option(
        "--reference", help="The reference specimen, fixed at 1.0 and never rated.")] = REFERENCE_SPECIMEN,
    specimens: RatingsSpecimens = None,
    force: Annotated[bool, typer.Option("--force", help="Replace SUMMARY.csv if it exists.")] = False,
) -> None:
    """Summarise magnitude estimates into the perceived roughness of each specimen (section 3.1).

    Per specimen: each participant's median over sessions, then the geometric mean over participants (gmean); sd
    is the sample SD (ddof=1) of those medians. The reference is written as gmean 1.0 with an empty sd. A
    participant missing a session or a trial is a warning on stderr and the summary goes on; a bad row is an error
    naming its line, and nothing is written.
    """
    from .._util.atomic import check_can_write, write_csv
    from ..analysis.magnitude_estimation import aggregate_ratings
    from ..io.names import check_name
    from ..io.ratings_file import read_ratings

    check_can_write(out, force=force, inputs=[ratings_file, *_specimens_file(specimens)])
    check_name(reference, what="--reference")
    names = _specimen_names(specimens) if specimens is not None else None
    frame = read_ratings(ratings_file, specimens=names, reference=reference)
    with warnings.catch_warnings():
        warnings.simplefilter("always", RoughsenseWarning)  # every gap, even two with the same words
        summary = aggregate_ratings(frame, reference, specimens=names, path=ratings_file)
    write_csv(out, summary)
    _print_summary(summary, reference)
    print(f"wrote {out}")


ScheduleOut = Annotated[Path, typer.Option(
    "--out", "-o", help="Schedule CSV: participant, session, order, specimen, and an empty rating column to fill in.")]
ProtocolSpecimens = Annotated[str | None, typer.Option(
    "--specimens", show_default=False,
    help="Comma list (names, or a set of the twin's: paper, paper+grooves) or a study's specimens.csv. Default: the "
         "paper's R2..R5, C2..C5. Unless the set already varies the land at one period, protocol also recommends "
         "gratings to print that tell period from groove width, and says why.")]
Sheet = Annotated[Path | None, typer.Option(
    "--sheet", show_default=False,
    help="Also write a printable sheet: .html (print from a browser) or .md (can be filled in and read back).")]


def protocol(
    out: ScheduleOut,
    seed: Annotated[int, typer.Option(
        "--seed", parser=_SEED, help="Seed of the random orders (same seed, same schedule).")] = defaults.SEED,
    participants: Annotated[int, typer.Option(
        "--participants", parser=_PARTICIPANTS, help="Number of participants (IDs P01, P02, ...).")] = PAPER_PARTICIPANTS,
    sessions: Annotated[int, typer.Option("--sessions", parser=_SESSIONS, help="Sessions per participant.")] = PAPER_SESSIONS,
    specimens: ProtocolSpecimens = None,
    reference: Annotated[str, typer.Option(
        "--reference", help="The reference specimen: never presented for rating.")] = REFERENCE_SPECIMEN,
    sheet: Sheet = None,
    force: Annotated[bool, typer.Option("--force", help="Replace existing output files.")] = False,
) -> None:
    """Draw randomised presentation orders for a magnitude-estimation experiment (section 3.1).

    Every specimen except the reference appears once per session, in an order drawn afresh for every participant
    and session. Fill in the rating column of the schedule (or of a Markdown sheet) and pass it to `roughsense
    ratings` as it is.
    """
    import numpy as np

    from .._util.atomic import check_outputs, write_csv, write_text
    from ..analysis.magnitude_estimation import make_schedule
    from ..io.names import check_name
    from ..report.ratings_sheet import groove_advice, render_sheet

    _check_panel(participants, sessions, 1)  # the counts alone, before anything is read or drawn
    check_seed(seed)
    check_name(reference, what="--reference")
    fmt = _sheet_format(sheet)
    check_outputs({"--out": out, "--sheet": sheet}, force=force, inputs=_specimens_file(specimens))
    names = _specimen_names(specimens) if specimens is not None else list(PAPER_SPECIMENS)
    _check_panel(participants, sessions, len({n for n in names if n != reference}))
    schedule = make_schedule(names, participants, sessions, reference, rng=np.random.default_rng(seed))
    advice = groove_advice(_groove_gratings(specimens, names))
    text = render_sheet(schedule, fmt, reference=reference, csv_name=out.name, advice=advice) if fmt else None
    write_csv(out, schedule)
    if text is not None:
        write_text(sheet, text)
    shown = schedule["specimen"].nunique()
    print(f"wrote {out}: {counted(participants, 'participant')} x {counted(sessions, 'session')} x "
          f"{counted(shown, 'specimen')} "
          f"(reference {reference} excluded)")
    if sheet is not None:
        print(f"wrote {sheet}")
    for paragraph in advice:
        print(paragraph)


def _groove_gratings(value: str | None, names: list[str]) -> list[str]:
    """The twin's groove gratings (sim.specimens.GROOVE_SPECS) the set ``names`` lacks, by period and land fraction
    (analysis/geometry.py); none where the set already has two rectangular geometries at one period.

    A set's geometry is read from its specimens.csv (``value``), else from the names the twin knows (presets,
    specs' names such as rect_3_1_1); a name it does not know adds nothing."""
    from collections import Counter

    from ..analysis.geometry import RECTANGULAR, land_fractions, land_label
    from ..sim.specimens import GROOVE_SPECS, parse_specimen

    table = _specimens_table(value, names)
    rectangles = table[table["shape"] == RECTANGULAR]
    have = {(float(period), land_label(fraction))
            for period, fraction in zip(rectangles["wavelength_mm"], land_fractions(rectangles)) if fraction == fraction}
    if any(count > 1 for count in Counter(period for period, _ in have).values()):
        return []
    wanted = []
    for spec in GROOVE_SPECS:
        grating = parse_specimen(spec)
        if (grating.wavelength_mm, land_label(grating.ridge_width_mm / grating.wavelength_mm)) not in have:
            wanted.append(spec)
    return wanted


def _specimens_table(value: str | None, names: list[str]):
    """The set's specimens.csv (``value`` naming one), else the rows of the names the twin parses."""
    import pandas as pd

    from ..errors import ConfigError as Unknown
    from ..io.study import read_specimens
    from ..sim.specimens import parse_specimen

    if value is not None and _specimens_file(value):
        return read_specimens(Path(value))
    rows = []
    for name in names:
        for text in (name, name.replace("_", ":")):  # a preset (R3), or a spec's name (rect_3_1_1 is rect:3:1:1)
            try:
                rows.append(parse_specimen(text).table_row())
                break
            except Unknown:
                continue
    return pd.DataFrame(rows, columns=["specimen", "shape", "wavelength_mm", "ridge_width_mm", "groove_width_mm"])


def _check_panel(participants: int, sessions: int, specimens: int) -> None:
    """--participants and --sessions within the schedule's stated bounds (analysis.magnitude_estimation.MAX_*)."""
    from ..analysis.magnitude_estimation import schedule_size_problem

    for name, value in (("--participants", participants), ("--sessions", sessions)):
        if value < 1:
            raise ConfigError(f"{name} must be at least 1, got {value}")
    problem = schedule_size_problem(participants, sessions, specimens)
    if problem:
        raise ConfigError(problem)


def _specimens_file(specimens: str | None) -> list[Path]:
    """--specimens as an input of the run when it names a file (it may be a comma list)."""
    return [Path(specimens)] if specimens is not None and Path(specimens).is_file() else []


def _sheet_format(sheet: Path | None) -> str | None:
    """'html' or 'markdown' from the sheet's suffix (None without a sheet); refused before anything is written."""
    if sheet is None:
        return None
    fmt = {".html": "html", ".htm": "html", ".md": "markdown", ".markdown": "markdown"}.get(sheet.suffix.lower())
    if fmt is None:
        raise ConfigError(f"--sheet must end in .html or .md, got {sheet.name!r}")
    return fmt


def register(app: typer.Typer) -> None:
    app.command("ratings")(ratings)
    app.command("protocol")(protocol)
