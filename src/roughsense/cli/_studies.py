"""Study folders named on the command line: a path, or ``builtin`` for the simulated paper study.

``builtin`` is a reserved word wherever a study folder is accepted (``--study``): it
names the paper's study as the digital twin simulates it with ``--seed``, generated once into the cache and reused.
``builtin:SET`` is the same study on a named specimen set of the twin (``sim.specimens.SPECIMEN_SETS``, e.g.
``builtin:paper+grooves``; ``builtin:paper`` is ``builtin``), cached under its own name.
A real folder called ``builtin`` is reached as ``./builtin`` (any path with a separator is a path).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Annotated

import typer

from ._common import number_option, progress

BUILTIN = "builtin"
STUDY_METAVAR = "DIR|builtin[:SET]"
#: ``--seed`` of a command whose only seed is the built-in study's (check, calibrate).
BuiltinSeed = Annotated[int, typer.Option(
    "--seed", parser=number_option("--seed", quantity="seed"),
    help="Seed of the built-in simulated study, when the folder is builtin.")]
#: Where the built-in study's simulation starts, and the package data it reads: the cache key covers both.
SIMULATOR_ENTRY_POINTS = ("roughsense.sim.simulate",)
SIMULATOR_DATA = ("roughsense.data.paper",)


def builtin_set(value: str | os.PathLike[str] | None) -> str | None:
    """The specimen set a ``builtin`` or ``builtin:SET`` value names (``paper`` for the bare word); None for a path.
    An unknown set is refused, naming the sets there are."""
    if not isinstance(value, str):
        return None
    word, colon, name = value.partition(":")
    if word != BUILTIN:
        return None
    from ..errors import ConfigError
    from ..paper import REFERENCE_SPECIMEN
    from ..sim.specimens import PAPER_SET, SPECIMEN_SETS, check_specimen_set

    if not colon:
        return PAPER_SET
    key = check_specimen_set(name, option=repr(value))
    if REFERENCE_SPECIMEN not in SPECIMEN_SETS[key]:  # the paper's study is rated against R3
        raise ConfigError(f"{value!r}: the set {key} lacks the reference {REFERENCE_SPECIMEN}, which the built-in "
                          f"study is rated against; sets with it: "
                          f"{', '.join(k for k, v in SPECIMEN_SETS.items() if REFERENCE_SPECIMEN in v)}")
    return key


def is_builtin(value: str | os.PathLike[str] | None) -> bool:
    return builtin_set(value) is not None


def simulator_fingerprint() -> str:
    """A hash of the simulator's source (every module it imports) and data: a changed twin never reuses a stale study."""
    from .._util.fingerprint import code_fingerprint

    return code_fingerprint(*SIMULATOR_ENTRY_POINTS, data_packages=SIMULATOR_DATA)


def _stem(seed: int, specimen_set: str | None = None) -> str:
    """The cache entry's name: the set is part of it (a set's study is never the paper's), the paper's unchanged.
    Sets' names end before ``-seed`` so no stem is another's prefix (the cache clears a stem's other versions)."""
    from ..sim.specimens import PAPER_SET

    if specimen_set in (None, PAPER_SET):
        return f"simulated-study-seed{seed}"
    return f"simulated-study-{specimen_set.replace('+', '-')}-seed{seed}"


def builtin_study_path(seed: int, specimen_set: str | None = None) -> Path:
    """Where the built-in study of ``seed`` (on ``specimen_set``) lives (or will live) in the cache."""
    from .._util.cache import folder_entry

    return folder_entry(_stem(seed, specimen_set), simulator_fingerprint())


def builtin_study(seed: int, jobs: int | None = None, specimen_set: str | None = None) -> Path:
    """The simulated paper study (on the twin's ``specimen_set``; default the paper's 14), generated once per seed, set
    and simulator version into the cache, reused after.

    The cache (``_util/cache.cached_folder``) keeps the entry whole; this says what goes in it.
    """
    from .._util.cache import cached_folder
    from ..sim import simulate as sim
    from ..sim.config import SimulationConfig
    from ..sim.overwrite import is_complete_simulation
    from ..sim.specimens import PAPER_SET

    config = None if specimen_set in (None, PAPER_SET) else SimulationConfig(specimens=(specimen_set,))
    what = "" if config is None else f" on the specimen set {specimen_set}"

    def simulate(root: Path, key_files: dict[str, str]) -> None:
        print(f"roughsense: simulating the paper's study{what} (seed {seed}) into {root}; first use only, "
              "later runs reuse it", file=sys.stderr, flush=True)
        sim.simulate_study(root, config, seed=seed, jobs=jobs, force=True, progress=progress, markers=key_files)

    return cached_folder(_stem(seed, specimen_set), simulator_fingerprint(), simulate,
                         is_complete=is_complete_simulation)


def resolve_study(value: str | os.PathLike[str], *, seed: int, jobs: int | None = None) -> Path:
    """``builtin[:SET]`` -> the built-in study of ``seed`` on that set (simulated on first use); anything else is a
    path."""
    specimen_set = builtin_set(value)
    if specimen_set is None:
        return Path(value)
    if Path(value).exists():
        print(f"roughsense: note: {value!r} names the built-in simulated study; for the folder here, "
              f"write ./{value}", file=sys.stderr)
    return builtin_study(seed, jobs, specimen_set)


def study_folder(value: str | os.PathLike[str], seed: int) -> Path:
    """A study folder given as a command's argument (``check DIR``, ``calibrate DIR``): ``builtin`` is the built-in
    study of ``seed`` (:data:`BuiltinSeed`), as ``--study builtin`` is."""
    return resolve_study(value, seed=seed)


def builtin_writable(value: str | os.PathLike[str]) -> bool:
    """False for ``builtin``, with one line saying why nothing is written into it: the built-in study is the cache's
    (rebuilt whenever the simulator changes), so a value written into its study.toml would be lost, and it would no
    longer be the study its cache key names."""
    if not is_builtin(value):
        return True
    print(f"roughsense: note: {BUILTIN} is the cache's simulated study: measured and printed, nothing written into it",
          file=sys.stderr)
    return False


def checked_scale(study, *, pad: str | None = None):
    """The study with its scale checked (``model/scale_check.py``): read at the measured px/mm where its stated one is
    off beyond the tolerance, else as stated. Returns the study to use and the check's line (for the report or the
    model file; :func:`echo_scale` prints it once the run has succeeded, so a failing run's error stands alone)."""
    from ..model.scale_check import check_study_scale, corrected

    check = check_study_scale(study, pad=pad)
    return (corrected(study, check), check.correction()) if check.off else (study, check.summary())


def echo_scale(line: str) -> None:
    """A scale check's line on stderr: a warning where the scale was corrected, else a note."""
    import warnings

    from ..errors import RoughsenseWarning
    from ..model.scale_check import CORRECTED

    if CORRECTED in line:
        warnings.warn(RoughsenseWarning(line), stacklevel=2)
    else:
        print(f"roughsense: {line}", file=sys.stderr)
