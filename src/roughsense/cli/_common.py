"""Small helpers shared by the command modules: option parsing and the progress display."""
from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, TypeVar

import typer

from .. import defaults
from .._util import interrupt
from .._util.workers import MAX_JOBS_PER_CORE, usable_cores
from ..errors import ConfigError

T = TypeVar("T")

#: Exit status of a run that finished but withheld some presses (predict's rows the gate or an unreadable image
#: withheld; capture's presses the model's gate would withhold): the output is written for the others.
WITHHELD_EXIT = 3


def number_option(option: str, *, quantity: str = "", low: float | None = None, high: float | None = None,
                  low_open: bool = False, whole: bool = False, must: str | None = None):
    """A typer ``parser=`` reading ``option``'s value as a CSV cell is read (:func:`roughsense.io.numbers.parse_number`).

    typer would take ``1_0`` as 10, ``١`` as 1 and ``inf``. A value not spelled as a number is a usage error, as
    click's own (``invalid value for '--seed': not a number: '1_0' (...)``); a number that is not finite or out of
    its bounds reads ``OPTION must be MUST, got VALUE`` (``must``: the wording of the command's own check).
    """
    def parse(text: str):
        from .._util.checks import short_repr
        from ..io.numbers import NumberError, parse_number  # not at import: --help stays light

        try:
            return parse_number(text, quantity=quantity, low=low, high=high, low_open=low_open, whole=whole)
        except NumberError as exc:
            if exc.message.startswith("not a number"):
                raise typer.BadParameter(exc.message) from None
            if must is not None or exc.message.startswith("not a finite"):
                raise ConfigError(f"{option} must be {must or 'a finite number'}, got {short_repr(text)}") from None
            raise ConfigError(f"{option} {exc.message}") from None

    return parse


def parse_float_list(text: str, *, name: str) -> list[float]:
    """Parse "1,2,3" into floats (each by the one number parser), refusing blanks, non-numbers and non-positive values."""
    from .._util.checks import short_repr
    from ..io.numbers import NumberError, parse_number, spelling_hint  # not at import: --help stays light

    values = []
    for part in text.split(","):
        part = part.strip()
        try:
            value = float(parse_number(part))
        except NumberError as exc:
            if exc.message.startswith("not a finite"):
                raise ConfigError(f"--{name}: {short_repr(part)} must be positive") from None
            raise ConfigError(f"--{name}: {short_repr(part)} is not a number{spelling_hint(part)}") from None
        if not value > 0:
            raise ConfigError(f"--{name}: {short_repr(part)} must be positive")
        values.append(value)
    return values


def check_seed(seed: int) -> int:
    """A seed for numpy.random.default_rng: a whole number >= 0 (a negative one is refused by NumPy)."""
    from .._util.checks import MAX_SEED, SEED, check  # numpy: not for --help

    return check(seed, SEED, name="--seed", must=f"a whole number from 0 to {MAX_SEED}")


def run_inputs(*files: os.PathLike[str] | str | Iterable, study: os.PathLike[str] | str | None = None) -> list[Path]:
    """Every path a run reads: ``files`` (paths or lists of them) and, for a study folder, its files and images/.

    What no ``--out`` of the run may be (:func:`roughsense._util.atomic.refuse_inputs`). ``builtin`` (and
    ``builtin:SET``, cli/_studies.py) is the cache's.
    """
    paths = [Path(f) for item in files for f in ([item] if isinstance(item, (str, os.PathLike)) else item)]
    if study is None or str(study) == "builtin" or str(study).startswith("builtin:"):
        return paths
    root = Path(study)
    names = ("study.toml", "specimens.csv", "manifest.csv", "ratings.csv", "images")  # io.study's contract
    return [*paths, *(root / name for name in names), *_manifest_images(root)]


def _manifest_images(root: Path) -> list[Path]:
    """The images the study's manifest lists: its paths are relative to the folder, so an image may lie anywhere in
    it, not only in images/. Read leniently, as text: a manifest that does not read is reported with the study."""
    import csv

    from ..errors import RoughsenseError
    from ..io.csv_read import MAX_CSV_BYTES, read_text

    try:
        lines = read_text(root / "manifest.csv", max_bytes=MAX_CSV_BYTES).splitlines()
    except RoughsenseError:
        return []
    delimiter = ";" if lines and ";" in lines[0] and "," not in lines[0] else ","  # as io.csv_read reads it
    try:  # a cell past csv's field limit (a forged path) is the study reader's to report, in its own words
        rows = list(csv.reader(lines, delimiter=delimiter, skipinitialspace=True))
    except csv.Error:
        return []
    header = [cell.strip().lower() for cell in (rows[0] if rows else [])]
    if "image" not in header:
        return []
    column = header.index("image")
    return [root / row[column].strip() for row in rows[1:] if len(row) > column and row[column].strip()]


def _every_core(jobs: int | None) -> int:
    if jobs is not None and jobs < 1:  # checked here, not with typer's min=1: its range label crowds the help
        raise ConfigError(f"--jobs must be at least 1, got {jobs} (leave it out to use every core)")
    limit = MAX_JOBS_PER_CORE * usable_cores()
    if jobs is not None and jobs > limit:
        raise ConfigError(f"--jobs must be at most {limit} ({MAX_JOBS_PER_CORE} per usable core), got {jobs}")
    return usable_cores() if jobs is None else jobs


#: ``--jobs``'s one meaning, how many things at once, on every command that has it (``n_jobs`` in Python).
JOBS_HELP = ("How much to run at once: images decoded, trials simulated, models fitted, sweep cells computed "
             "(default: all cores). The results do not depend on it.")
#: ``--jobs`` on every command that has it: one default (all cores). explore's is its own (batch jobs on a queue).
Jobs = Annotated[int | None, typer.Option(
    "--jobs", "-j", show_default=False, callback=_every_core, parser=number_option("--jobs", whole=True),
    help=JOBS_HELP)]


def check_figure_format(text: str) -> str:
    """``--figure-format``: png, svg or pdf (any case), else one line naming the choices."""
    if text.lower() not in defaults.FIGURE_FORMATS:
        raise ConfigError(f"--figure-format must be one of {', '.join(defaults.FIGURE_FORMATS)}, got {text!r}")
    return text.lower()


#: ``--figure-format`` and ``--dpi`` on every command that draws figures (study, explore).
FigureFormat = Annotated[str, typer.Option(
    "--figure-format", help="Format of the figure files: png, svg (vector, embedded as is) or pdf (vector; the page "
    "shows a PNG of each figure and links its PDF).")]
Dpi = Annotated[int, typer.Option(
    "--dpi", parser=number_option("--dpi", whole=True, low=30, high=1200),
    help="Resolution of the figures' raster parts in dots per inch (30 to 1200; a figure is held within 24 Mpx, "
         "drawn at the resolution that fits).")]


#: How each command's pixel limit is raised, said after an image above it (io.images.PixelLimitError): only what the
#: command has. A study's [sensor] max_pixels is read by the commands that read a study; predict's limit is fixed.
PIXEL_LIMIT_ADVICE = {
    "features": "pass --max-pixels (or raise [sensor] max_pixels in study.toml) if it is genuine",
    **dict.fromkeys(("study", "fit", "calibrate", "check"), "raise [sensor] max_pixels in study.toml if it is genuine"),
}


def limit_advice(error: Exception, command: str | None) -> str:
    """"; how to raise the limit" after an image above the pixel limit, as ``command`` can, else ""."""
    images = sys.modules.get("roughsense.io.images")  # loaded if it raised: --help never imports it
    if images is None or not isinstance(error, images.PixelLimitError) or command not in PIXEL_LIMIT_ADVICE:
        return ""
    return f"; {PIXEL_LIMIT_ADVICE[command]}"


#: The narrowest a text column (an image path) is cut to when a table must fit the terminal.
MIN_TEXT_COLUMN = 12


def terminal_table(frame, *, float_format=None) -> str:
    """``frame`` as text within the terminal's width (``shutil.get_terminal_size``: the terminal's, else $COLUMNS,
    else 80), one line per row. pandas' ``to_string`` where it fits; else a long text cell (an image path) keeps its
    end ("...images/R3_1N_r01.png") and a header wider than its column wraps, where pandas broke the table into
    blocks joined by a backslash. A number is never cut."""
    import shutil

    width = shutil.get_terminal_size().columns
    plain = frame.to_string(index=False, float_format=float_format)
    if max(map(len, plain.splitlines()), default=0) <= width or frame.empty:
        return plain
    names = [str(c) for c in frame.columns]
    cells = [[float_format(v) if float_format is not None and isinstance(v, float) else str(v) for v in frame.iloc[:, k]]
             for k in range(len(names))]
    from ..io.numbers import NUMBER

    numeric = [all(NUMBER.fullmatch(v.strip()) or v.strip().lower() == "nan" for v in column) for column in cells]
    widths = _column_widths(names, cells, numeric, width)
    heads = [_wrapped_header(name, w) for name, w in zip(names, widths)]
    lines = [["" if i >= len(head) else head[i] for head in heads] for i in range(max(map(len, heads)))]
    lines += [[_cut_start(column[row], w) for column, w in zip(cells, widths)] for row in range(len(frame))]
    return "\n".join("  ".join(value.rjust(w) if is_number else value.ljust(w)
                                for value, w, is_number in zip(line, widths, numeric)).rstrip() for line in lines)


def _column_widths(names: list[str], cells: list[list[str]], numeric: list[bool], width: int) -> list[int]:
    """Numbers as wide as their longest value or their header's longest word (``roughness_`` of
    ``roughness_rel_R3``); text shares the rest (at least MIN_TEXT_COLUMN each); room left over widens the narrow
    headers first."""
    words = [max(len(w) for w in name.replace("_", "_ ").split() or [""]) for name in names]
    longest = [max(max(map(len, column)), min(word, MIN_TEXT_COLUMN) if n else 0)
               for column, word, n in zip(cells, words, numeric)]
    room = width - 2 * (len(names) - 1) - sum(w for w, n in zip(longest, numeric) if n)
    natural = {k: max(longest[k], len(names[k])) for k, n in enumerate(numeric) if not n}
    widths = list(longest)
    for i, k in enumerate(sorted(natural, key=natural.get)):  # the narrow take what they need, the wide share
        widths[k] = min(natural[k], max(MIN_TEXT_COLUMN, room // (len(natural) - i)))
        room -= widths[k]
    spare = width - 2 * (len(names) - 1) - sum(widths)
    for k in sorted(range(len(names)), key=lambda k: len(names[k]) - widths[k]):
        grow = min(max(0, len(names[k]) - widths[k]), max(0, spare))
        widths[k] += grow
        spare -= grow
    return [max(1, w) for w in widths]


def _wrapped_header(name: str, width: int) -> list[str]:
    """A header on as many lines as its column needs, broken after an underscore where it can."""
    parts = [p for p in name.replace("_", "_\0").split("\0") if p]
    lines = [""]
    for part in parts:
        while len(part) > width:  # a part longer than the column: cut it
            if lines[-1]:
                lines.append("")
            lines[-1], part = part[:width], part[width:]
            lines.append("")
        if len(lines[-1]) + len(part) > width and lines[-1]:
            lines.append("")
        lines[-1] += part
    return [line for line in lines if line] or [""]


def _cut_start(text: str, width: int) -> str:
    """``text`` within ``width``, its start dropped (a path's end names the file)."""
    return text if len(text) <= width else "\u2026" + text[len(text) - width + 1:]


def parse_name_list(text: str) -> list[str]:
    return [p.strip() for p in text.split(",") if p.strip()]


def _interactive() -> bool:
    return sys.stderr.isatty()


#: A step quicker than this shows nothing off a terminal: a short command (or a bad-input error) stays quiet.
ANNOUNCE_AFTER_S = 2.0

_lock = threading.RLock()
_open: list[_LogLine] = []  # the stage whose log line is written without its end, if any


def close_line() -> None:
    """End an open stage line, so that an error or a warning printed now starts on a line of its own."""
    with _lock:
        if _open:
            _open.clear()
            print(file=sys.stderr, flush=True)


class _LogLine:
    """One stage off a terminal: ``roughsense: simulating (840) ... done in 91.2 s``.

    The start is written once the stage has run ANNOUNCE_AFTER_S (from a timer, so a slow first item
    counts too) and completed when the stage ends, so a log shows what is running and how long it took.
    """

    def __init__(self, description: str, total: int | None) -> None:
        self.text = description if total is None else f"{description} ({total})"
        self.total = total
        self.started = time.perf_counter()
        self.announced = self.ended = False
        self.timer = threading.Timer(ANNOUNCE_AFTER_S, self._announce)
        self.timer.daemon = True
        self.timer.start()

    def _announce(self) -> None:
        with _lock:
            if self.ended:
                return
            close_line()
            print(f"roughsense: {self.text} ...", end="", file=sys.stderr, flush=True)
            self.announced = True
            _open.append(self)

    def finish(self, done: int | None = None, *, failed: bool = False) -> None:
        self.timer.cancel()
        with _lock:
            self.ended = True
            if not (self.announced and _open and _open[-1] is self):  # quick, or closed by an error/warning
                return
            _open.clear()
            elapsed = time.perf_counter() - self.started
            if done is not None and self.total is not None and done < self.total:
                failed = True
            count = f" {done} of {self.total}," if failed and done is not None and self.total is not None else ""
            text = f" stopped after{count} {elapsed:.1f} s" if failed else f" done in {elapsed:.1f} s"
            print(text, file=sys.stderr, flush=True)


def progress(items: Iterable[T], *, total: int | None = None, description: str = "") -> Iterator[T]:
    """Show a long loop: a rich bar with an estimate on a terminal, one line on stderr otherwise.

    Library functions take this as an optional ``progress`` callback and print nothing themselves.
    """
    if not _interactive():
        line = _LogLine(description, total)
        done = 0
        try:
            for item in items:
                interrupt.check()  # a safe point: each item
                yield item
                done += 1
        finally:
            line.finish(done)
        return
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
               TextColumn("eta"), TimeRemainingColumn())
    with Progress(*columns, transient=True, console=_console()) as bar:
        task = bar.add_task(description, total=total)
        for item in items:
            interrupt.check()  # a safe point: each item
            yield item
            bar.advance(task)


@contextmanager
def stage(description: str) -> Iterator[None]:
    """A step with no count (writing a report): a spinner with the elapsed time, or one line."""
    interrupt.check()  # a safe point: before each stage
    if not _interactive():
        line = _LogLine(description, None)
        try:
            yield
        except BaseException:
            line.finish(failed=True)  # the error line that follows says why
            raise
        line.finish()
        return
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(), transient=True,
                  console=_console()) as bar:
        bar.add_task(description, total=None)
        yield


def _console():
    from rich.console import Console

    return Console(stderr=True)
