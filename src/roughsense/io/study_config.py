"""study.toml, table by table: its known tables and keys, the parse that warns about unknown ones (and refuses a
misspelt one that would silently leave its defaults), and the readers of ``[sensor]`` and ``[pads.NAME]``.

The other tables are read where they are used: ``[protocol]`` by :mod:`.protocol`, ``[study]`` by :mod:`.study`.
"""
from __future__ import annotations

import os
import tomllib
import warnings
from collections.abc import Mapping
from pathlib import Path

from .._util.checks import is_number, short_repr
from ..defaults import MAX_PIXELS, PX_PER_MM, ROI
from ..errors import PASS_FORCE, ConfigError, InputError, RoughsenseWarning
from .csv_read import read_text
from .names import check_name
from .numbers import BOUNDS, toml_spelling_problem
from .sensor_settings import SensorSettings

#: Every table and key study.toml may hold. ``None`` means any key: the ``[simulation]`` table is the
#: simulator's own record of its settings. An unknown table or key is a warning naming it, so a typo such as
#: ``roi_typo`` is noticed. Add a key here when a reader starts using it.
CONFIG_KEYS: dict[str, frozenset[str] | None] = {
    "study": frozenset({"name", "reference_specimen", "synthetic"}),
    "sensor": frozenset({"px_per_mm", "roi", "max_pixels"}),
    "protocol": frozenset({"forces_n"}),
    "pads": None,  # one sub-table per pad name: [pads.fingerprint] ridge_period_mm = 1.0
    "simulation": None,
}
#: Keys of a ``[pads.NAME]`` sub-table.
PAD_KEYS = frozenset({"ridge_period_mm"})
#: A pad's ridge period is at most this (mm): ridges coarser than the specimens are not a fingerprint. Its lower
#: bound (1 um) keeps the ridge frequency 1/period finite; both are stated in :data:`.numbers.BOUNDS`.
MAX_RIDGE_PERIOD_MM = float(BOUNDS["ridge_period_mm"].high)
MIN_RIDGE_PERIOD_MM = float(BOUNDS["ridge_period_mm"].low)


#: study.toml is a few hundred bytes; a file far larger is not one (and is not read whole).
MAX_CONFIG_BYTES = 1_000_000
#: Deepest nesting of tables and arrays study.toml may hold. A study's own is 3 (``[pads.NAME] key``); every writer
#: of study.toml must be able to write back what ``check`` accepts, and tomlkit (``calibrate``) refuses arrays past
#: 100 levels, tomli-w (the study writer) past about 250: 32 is far above any study and far below both.
MAX_CONFIG_DEPTH = 32


def read_config(path: str | os.PathLike[str]) -> dict:
    """Parse study.toml and check its shape: known tables are tables; unknown tables and keys are warned about.

    Values are checked by the readers that use them (:func:`sensor_from_config`, :func:`parse_forces`).
    """
    path = Path(path)
    if not path.exists():  # a FIFO or a folder there is named by read_text, not "not found"
        raise InputError("file not found (every study folder needs study.toml)", path=path)
    text = read_text(path, max_bytes=MAX_CONFIG_BYTES)
    try:
        config = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"is not valid TOML ({exc})", path=path) from None
    except RecursionError:
        raise InputError("is not a study.toml: its values are nested too deeply", path=path) from None
    if (depth := nesting_depth(config)) > MAX_CONFIG_DEPTH:
        raise InputError(f"is not a study.toml: its values are nested too deeply ({depth} levels, at most "
                         f"{MAX_CONFIG_DEPTH}; a study's own nest 3), so no writer of study.toml could write it back",
                         path=path)
    problem = toml_spelling_problem(text)
    if problem is not None:  # TOML's own spellings (1_0, 0x2, inf) are not numbers to the CSVs: one spelling everywhere
        raise InputError(problem, path=path)
    for table, value in config.items():
        if table not in CONFIG_KEYS:
            kind = "table" if isinstance(value, dict) else "key"
            shadowed = shadowed_key(table, CONFIG_KEYS, set(config))
            if shadowed is not None:  # [sensors] would leave [sensor] and its scale at their defaults, unseen
                raise InputError(f"unknown {kind} {table!r} looks like a misspelt [{shadowed}], which is not there: its "
                                 f"defaults would be used; write [{shadowed}]", path=path)
            warnings.warn(f"{path}: unknown {kind} {table!r} ignored (known tables: {', '.join(CONFIG_KEYS)})",
                          RoughsenseWarning, stacklevel=2)
            continue
        if not isinstance(value, dict):
            raise InputError(f"{table} must be a table ([{table}] followed by key = value lines), "
                             f"got {type(value).__name__} {short_repr(value)}", path=path)
        known = CONFIG_KEYS[table]
        for key in value:
            if known is not None and key not in known:
                shadowed = shadowed_key(key, known, set(value))
                if shadowed is not None:  # px_per_mmm = 8.7 would leave px_per_mm at its default, unseen
                    raise InputError(f"[{table}] unknown key {key!r} looks like a misspelt {shadowed!r}, which is "
                                     f"not set: its default would be used; write {shadowed} = ...", path=path)
                warnings.warn(f"{path}: unknown key {key!r} in [{table}] ignored (known: {', '.join(sorted(known))})",
                              RoughsenseWarning, stacklevel=2)
    return config


def nesting_depth(value: object) -> int:
    """How many tables and arrays deep ``value`` nests (a bare value: 0), counted without recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, (dict, list)):
            deepest = max(deepest, depth + 1)
            stack.extend((child, depth + 1) for child in (node.values() if isinstance(node, dict) else node))
    return deepest


def shadowed_key(key: str, known, present) -> str | None:
    """The known key an unknown ``key`` is most likely a misspelling of (one not set beside it), else None: a match
    of 85 % by difflib's ratio or of the same letters without case and '_', '-' or spaces."""
    import difflib

    def plain(text: str) -> str:
        return "".join(ch for ch in text.lower() if ch.isalnum())

    missing = [k for k in known if k not in present]
    same = [k for k in missing if plain(k) == plain(key)]
    close = difflib.get_close_matches(key, missing, n=1, cutoff=0.85)
    return (same or close or [None])[0]


#: What a study.toml without a scale is told: every spectrum depends on it, so it is never assumed unsaid.
NO_SCALE = (f"[sensor] states no px_per_mm: the paper's {PX_PER_MM:g} px/mm is assumed, and every spectrum depends on it; "
            "measure this camera's with `roughsense calibrate DIR` (it writes px_per_mm here)")


def sensor_from_config(config: Mapping, path: Path, *, strict: bool = False) -> SensorSettings:
    """The ``[sensor]`` table as :class:`SensorSettings`. A missing px_per_mm is a problem with ``strict``
    (``roughsense check``), else one warning line naming the default taken."""
    sensor = config.get("sensor", {})
    if not isinstance(sensor, Mapping):
        raise InputError(f"sensor must be a table, got {type(sensor).__name__}", path=path)
    if "px_per_mm" not in sensor:
        if strict:
            raise InputError(NO_SCALE, path=path)
        warnings.warn(f"{path}: {NO_SCALE}", RoughsenseWarning, stacklevel=2)
    try:
        return SensorSettings(px_per_mm=sensor.get("px_per_mm", PX_PER_MM), roi=sensor.get("roi", ROI),
                              max_pixels=sensor.get("max_pixels", MAX_PIXELS))
    except ConfigError as exc:
        raise InputError(f"[sensor] {exc.message}", path=path) from None


def pad_ridge_periods(config: Mapping, path: Path) -> dict[str, float]:
    """``[pads.NAME] ridge_period_mm`` of every pad that states one, checked (a number of mm from 0.001 to 100)."""
    from .._util.checks import Real, check

    pads = config.get("pads", {})
    periods: dict[str, float] = {}
    for pad, table in pads.items():
        check_name(pad, path=path, what="[pads] pad name")
        if not isinstance(table, Mapping):
            raise InputError(f"[pads] {pad} must be a table ([pads.{pad}] followed by ridge_period_mm = ...), "
                             f"got {short_repr(table)}", path=path)
        for key in table:
            if key not in PAD_KEYS:
                warnings.warn(f"{path}: unknown key {key!r} in [pads.{pad}] ignored (known: {', '.join(sorted(PAD_KEYS))})",
                              RoughsenseWarning, stacklevel=2)
        if "ridge_period_mm" in table:
            try:
                periods[pad] = check(table["ridge_period_mm"], Real(MIN_RIDGE_PERIOD_MM, MAX_RIDGE_PERIOD_MM),
                                     name=f"[pads.{pad}] ridge_period_mm", must=f"a number of mm from "
                                     f"{MIN_RIDGE_PERIOD_MM:g} to {MAX_RIDGE_PERIOD_MM:g}")
            except ConfigError as exc:
                raise InputError(exc.message, path=path) from None
    return periods


def write_px_per_mm(toml_path, px_per_mm: float, *, note: str, force: bool = False) -> float | None:
    """Set ``[sensor] px_per_mm`` in a study.toml, keeping every other line, comment and layout (tomlkit), written
    atomically; ``note`` becomes the value's comment (what was measured, and how precisely).

    The file keeps its permissions (a 0600 study.toml stays 0600) and its UTF-8 byte-order mark where it has one:
    ``check`` and every reader accept it (``csv_read.read_text``), and the one value changed is the only byte a user
    should find changed. A scale already stated and different is the user's: replaced only with ``force``. Returns
    the value replaced (None where there was none).
    """
    import codecs
    import stat
    from pathlib import Path

    import tomlkit

    from .._util.atomic import atomic_open
    from .._util.files import open_regular

    path = Path(toml_path)
    raw, mode = b"", None
    try:
        if path.exists():
            with os.fdopen(open_regular(path), "rb") as handle:
                raw, mode = handle.read(MAX_CONFIG_BYTES + 1), stat.S_IMODE(os.fstat(handle.fileno()).st_mode)
        bom = codecs.BOM_UTF8 if raw.startswith(codecs.BOM_UTF8) else b""
        document = tomlkit.parse(raw[len(bom):].decode("utf-8"))
    except (OSError, UnicodeDecodeError, tomlkit.exceptions.ParseError) as exc:
        raise InputError(f"cannot read it to write px_per_mm ({exc})", path=path) from None
    sensor = document.get("sensor")
    if sensor is None:
        sensor = tomlkit.table()
        document["sensor"] = sensor
    old = sensor.get("px_per_mm")
    previous = float(old) if is_number(old) else None
    if old is not None and not force and (previous is None or abs(previous - px_per_mm) > 1e-12 * px_per_mm):
        raise ConfigError(f"{path}: [sensor] px_per_mm is already {old!s} (yours); {PASS_FORCE} to replace it with "
                          f"the measured {px_per_mm:.5g}")
    item = tomlkit.item(float(round(px_per_mm, 4)))
    item.comment(note)
    sensor["px_per_mm"] = item
    with atomic_open(path, "wb", file_mode=mode) as handle:
        handle.write(bom + tomlkit.dumps(document).encode("utf-8"))
    return previous
