"""Magnitude estimation (paper §3.1): the perceived-roughness targets from ratings, and the protocol.

Participants rate each specimen against the reference (R3 = 1.0, never rated) in several sessions.
Per specimen, each participant's ratings are reduced to their median over sessions, and the medians
are combined by their geometric mean across participants -- the target the models learn. The SD
reported beside it is the sample SD (ddof=1) of those per-participant medians (see ``SD_DEFINITION``).

The protocol side draws the randomised presentation orders (:mod:`roughsense.report.ratings_sheet` prints them
for the experimenter); the schedule CSV has an empty ``rating`` column, so the filled-in schedule *is* a ratings file.
"""
from __future__ import annotations

import os
import warnings
from collections.abc import Sequence

import numpy as np
import pandas as pd

from .._util.checks import POSITIVE_INT, check
from ..errors import ConfigError, InputError, RoughsenseWarning
from ..io.ratings_file import natural_key
from ..paper import REFERENCE_SPECIMEN

SD_DEFINITION = (
    "sd = sample standard deviation (ddof=1) across participants of each participant's median rating "
    "over sessions (linear scale, not the geometric SD)"
)

SUMMARY_COLUMNS = ["specimen", "gmean", "sd", "n_participants", "n_sessions"]
SCHEDULE_COLUMNS = ["participant", "session", "order", "specimen", "rating"]


class MissingRatingsWarning(RoughsenseWarning):
    """A participant has no rating for some specimen in some session; the median uses what there is."""


# --------------------------------------------------------------------------- aggregation


def _warn_gaps(frame: pd.DataFrame, rated: Sequence[str], path) -> None:
    """One warning per participant x session with missing trials, so the message names the gap."""
    where = f"{path}: " if path is not None else ""
    sessions = sorted(frame["session"].unique(), key=natural_key)
    seen = frame.groupby(["participant", "session"])["specimen"].agg(set).to_dict()
    for participant in sorted(frame["participant"].unique(), key=natural_key):
        for session in sessions:
            got = seen.get((participant, session), set())
            if not got:
                message = f"participant {participant} has no ratings in session {session}; medians use the other sessions"
            else:
                lacking = [s for s in rated if s not in got]
                if not lacking:
                    continue
                message = f"participant {participant}, session {session}: no rating for {', '.join(lacking)}"
            warnings.warn(where + message, MissingRatingsWarning, stacklevel=3)


def aggregate_ratings(
    ratings: pd.DataFrame,
    reference: str = REFERENCE_SPECIMEN,
    *,
    specimens: Sequence[str] | None = None,
    path: str | os.PathLike[str] | None = None,
    warn: bool = True,
) -> pd.DataFrame:
    """Per specimen: geometric mean over participants of each participant's median over sessions.

    Columns specimen, gmean, sd, n_participants, n_sessions (``sd`` as in :data:`SD_DEFINITION`;
    ``n_sessions`` = distinct sessions in which the specimen was rated). The reference is a row of its
    own with gmean 1.0 and sd NaN. Rows follow ``specimens`` when given (each must then be rated),
    else natural order (C2 < C2.5 < ... < R5). A participant missing a session or a trial gets a
    :class:`MissingRatingsWarning` naming the gap (unless ``warn`` is false) and the analysis goes on.
    ``path`` only labels errors and warnings; frame rows are taken to be file lines ``index + 2``.
    ``ratings`` is a validated frame: from a reader, or from :func:`roughsense.io.ratings_file.validate_ratings`.
    """
    frame = ratings
    if frame.empty:
        raise InputError("no ratings to summarise", path=path)
    rated = sorted(frame["specimen"].unique(), key=natural_key)
    if specimens is not None:
        order = list(dict.fromkeys(specimens))
        unrated = [s for s in order if s != reference and s not in set(rated)]
        if unrated:
            raise InputError(f"no ratings at all for specimen(s) {', '.join(unrated)}", path=path)
        rated = [s for s in order if s != reference]
        if reference not in order:
            order = [reference, *order]
    else:
        order = sorted([*rated, reference], key=natural_key)
    if warn:
        _warn_gaps(frame, rated, path)
    medians = frame.groupby(["specimen", "participant"], sort=False)["rating"].median()
    n_sessions = frame.groupby("specimen")["session"].nunique()
    rows = []
    for specimen in order:
        if specimen == reference:
            rows.append({"specimen": specimen, "gmean": 1.0, "sd": np.nan, "n_participants": 0, "n_sessions": 0})
            continue
        per_participant = medians.loc[specimen].to_numpy(dtype=float)
        rows.append({
            "specimen": specimen,
            "gmean": float(np.exp(np.mean(np.log(per_participant)))),
            "sd": float(np.std(per_participant, ddof=1)) if per_participant.size > 1 else np.nan,
            "n_participants": int(per_participant.size),
            "n_sessions": int(n_sessions.loc[specimen]),
        })
    summary = pd.DataFrame(rows, columns=SUMMARY_COLUMNS)
    return summary.astype({"n_participants": np.int64, "n_sessions": np.int64})


# --------------------------------------------------------------------------- protocol

#: Largest panel a schedule (``protocol``) or a simulated panel (a sweep's ``participants``) may have: the paper
#: rated with 10; a thousand is a survey, not a magnitude-estimation session, and bounds the rows drawn.
MAX_PARTICIPANTS = 1000
#: Most sessions per participant (the paper: 3).
MAX_SESSIONS = 100
#: Most trials (rows) in one schedule or simulated panel: participants x sessions x rated specimens. A million rows
#: is a 30 MB CSV drawn in seconds; the paper's panel is 390.
MAX_SCHEDULE_ROWS = 1_000_000


def schedule_size_problem(participants: int, sessions: int, specimens: int, *,
                          names: tuple[str, str] = ("--participants", "--sessions")) -> str | None:
    """Why a panel of this size is refused (the bounds above, ``names`` labelling the counts), or None."""
    for name, value, limit in ((names[0], participants, MAX_PARTICIPANTS), (names[1], sessions, MAX_SESSIONS)):
        if value > limit:
            return f"{name} must be at most {limit}, got {value}"
    rows = participants * sessions * specimens
    if rows > MAX_SCHEDULE_ROWS:
        return (f"{names[0]} x {names[1]} x specimens = {participants} x {sessions} x {specimens} = {rows} trials, "
                f"above the limit of {MAX_SCHEDULE_ROWS}")
    return None


def participant_ids(count: int) -> list[str]:
    """P01 ... P10: zero-padded so that they sort and read well on a sheet."""
    width = max(2, len(str(count)))
    return [f"P{i:0{width}d}" for i in range(1, count + 1)]


def make_schedule(
    specimens: Sequence[str],
    participants: int | Sequence[str],
    sessions: int,
    reference: str = REFERENCE_SPECIMEN,
    rng: np.random.Generator | int | None = None,
) -> pd.DataFrame:
    """Presentation orders: every specimen but the reference once per session, shuffled afresh for
    every participant and session from ``rng`` (a Generator, or a seed for one).

    Columns participant, session, order, specimen and an empty ``rating`` column for the experimenter
    to fill; the filled-in schedule is then read by :func:`roughsense.io.ratings_file.read_ratings` as it is.
    """
    if rng is None:
        raise ConfigError("make_schedule needs rng (a numpy Generator or a seed) so the orders can be reproduced")
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    names = [str(s).strip() for s in specimens]
    if any(not n for n in names):
        raise ConfigError("specimen names must not be empty")
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ConfigError(f"specimen(s) listed twice: {', '.join(duplicates)}")
    shown = [n for n in names if n != reference]
    if not shown:
        raise ConfigError(f"no specimens to present besides the reference {reference}")
    sessions = check(sessions, POSITIVE_INT, name="sessions", must="at least 1")
    numbered = isinstance(participants, (bool, int, np.integer, np.bool_))
    count = check(participants, POSITIVE_INT, name="participants", must="at least 1") if numbered else len(participants)
    problem = schedule_size_problem(count, sessions, len(shown), names=("participants", "sessions"))
    if problem:  # before a single ID or row is made
        raise ConfigError(problem)
    if numbered:
        people = participant_ids(count)
    else:
        people = [str(p).strip() for p in participants]
        if not people or any(not p for p in people) or len(set(people)) != len(people):
            raise ConfigError("participant IDs must be non-empty and distinct")
    rows = []
    for person in people:
        for session in range(1, sessions + 1):
            for position, index in enumerate(rng.permutation(len(shown)), start=1):
                rows.append((person, session, position, shown[index], np.nan))
    return pd.DataFrame(rows, columns=SCHEDULE_COLUMNS)
