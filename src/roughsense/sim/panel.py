"""Simulated participants: magnitude estimates of each specimen relative to the reference R3 (= 1).

Model (log scale): rating = G_s * exp(mu_s + b_ps + e_psk), with a participant-by-specimen offset b ~ N(0, v_b)
(people differ in how rough a given grating feels to them) and session noise e ~ N(0, v_e). Per specimen, the
total log-variance v = v_b + v_e and the offset mu_s are calibrated so that the paper's aggregation (median over
sessions, then geometric mean over participants) equals the paper's value G_s in expectation, and the expected SD
across participants' medians equals the paper's SD (``ratings_source = paper``).

Every other specimen -- and, with ``ratings_from="physics"``, every specimen -- is felt by the simulated finger
(:mod:`roughsense.sim.finger`): participant i reports exp(a_i) * (S / S_R3) ** (b * exp(c_i)) * exp(e_ik), with
scale a_i and exponent c_i (mean-one factor exp(c_i)) drawn once per person (so they are shared by all the
specimens that person rates) and session noise e_ik per specimen (``ratings_source = physics``).
"""
from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pandas as pd

from .. import defaults
from .._util.checks import Options, check
from ..paper import PAPER_PARTICIPANTS, PAPER_SESSIONS, REFERENCE_SPECIMEN, perceived_roughness
from . import finger
from .specimens import Specimen

SESSION_SHARE = 0.3  # share of the log-variance that is session-to-session (not participant) noise
RATINGS_FROM = ("paper", "physics")
RATING_DECIMALS = 2
_CALIBRATION_PANELS = 4000


#: The seed key of the panel's draws: ``simulate`` and a sweep cell use it alike, so both rate a design the same.
PANEL_SPAWN_KEY = (4,)


@lru_cache(maxsize=1)
def paper_perceived() -> pd.DataFrame:
    """The paper's perceived roughness (gmean, SD across participants) indexed by specimen, as the panel reads it."""
    return perceived_roughness().set_index("specimen")


@dataclass(frozen=True)
class Percept:
    """Expected aggregated rating, its SD across participants, and where they come from ("paper" or "physics").

    ``log_ratio`` is the finger's log(S / S_R3) for physics percepts (nan for the paper's values).
    """

    gmean: float
    sd: float
    source: str
    log_ratio: float = float("nan")


def check_ratings_from(ratings_from: str) -> str:
    return check(ratings_from, Options(RATINGS_FROM), name="--ratings-from", must=f"one of {', '.join(RATINGS_FROM)}")


def percept(specimen: Specimen, *, ratings_from: str = defaults.RATINGS_FROM, sessions: int = PAPER_SESSIONS) -> Percept:
    """Expected aggregated rating and its spread across participants for one specimen.

    ``ratings_from="paper"``: the paper's value for its rated presets, the finger model for anything else;
    ``"physics"``: the finger model for every specimen.
    """
    check_ratings_from(ratings_from)
    if ratings_from == "paper" and specimen.preset:
        paper = paper_perceived()
        if specimen.name in paper.index:
            row = paper.loc[specimen.name]
            sd = float(row["perceived_sd"]) if pd.notna(row["perceived_sd"]) else 0.0
            return Percept(float(row["perceived_gmean"]), sd, "paper")
    log_ratio = finger.log_ratio(specimen)
    psych = finger.PSYCHOPHYSICS
    gmean = math.exp(psych.exponent * log_ratio)
    log_sd = psych.log_sd_of_medians(log_ratio, sessions)
    return Percept(gmean, gmean * math.sqrt(math.expm1(log_sd**2)), "physics", log_ratio)


def _standard_draws(participants: int, sessions: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(20250425)  # fixed: the calibration is a property of the model, not of a run
    z_b = rng.standard_normal((_CALIBRATION_PANELS, participants))
    z_e = np.median(rng.standard_normal((_CALIBRATION_PANELS, participants, sessions)), axis=2)
    return z_b, z_e


@lru_cache(maxsize=256)
def log_parameters(gmean: float, sd: float, participants: int = 10, sessions: int = 3) -> tuple[float, float, float]:
    """(mu, v_b, v_e) such that E[aggregate] = gmean and E[SD of participants' medians] = sd."""
    if sd <= 0:
        return 0.0, 0.0, 0.0
    z_b, z_e = _standard_draws(participants, sessions)

    def moments(v: float) -> tuple[float, float]:
        logs = math.sqrt((1 - SESSION_SHARE) * v) * z_b + math.sqrt(SESSION_SHARE * v) * z_e
        mu = -math.log(np.mean(np.exp(logs.mean(axis=1))))
        medians = gmean * np.exp(mu + logs)
        return mu, float(np.mean(medians.std(axis=1, ddof=1)))

    lo, hi = 0.0, 4.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if moments(mid)[1] < sd:
            lo = mid
        else:
            hi = mid
    v = 0.5 * (lo + hi)
    mu, _ = moments(v)
    return mu, (1 - SESSION_SHARE) * v, SESSION_SHARE * v


def draw_log_ratings(gmean: float, sd: float, rng: np.random.Generator, *, panels: int = 1,
                     participants: int = 10, sessions: int = 3) -> np.ndarray:
    """Ratings of ``panels`` independent panels, shape (panels, participants, sessions)."""
    mu, v_b, v_e = log_parameters(float(gmean), float(sd), participants, sessions)
    b = rng.normal(0.0, math.sqrt(v_b), (panels, participants, 1))
    e = rng.normal(0.0, math.sqrt(v_e), (panels, participants, sessions))
    return gmean * np.exp(mu + b + e)


def _rng(seed: int, spawn_key: tuple[int, ...], *key: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(*spawn_key, *key)))


def draw_people(seed: int, spawn_key: tuple[int, ...], participants: int) -> tuple[np.ndarray, np.ndarray]:
    """Each participant's log scale a_i and exponent factor exp(c_i) (the finger model's people).

    c_i ~ N(-exponent_sd^2 / 2, exponent_sd^2), so the factor averages 1 and the panel's expected log aggregate is
    the model's exponent times log(S / S_R3). Keyed by the seed alone (not by any specimen), so a person is the
    same for every specimen they rate.
    """
    psych = finger.PSYCHOPHYSICS
    z = _rng(seed, spawn_key, 3).standard_normal((participants, 2))
    return psych.scale_sd * z[:, 0], np.exp(psych.exponent_sd * z[:, 1] - 0.5 * psych.exponent_sd**2)


def simulate_panel(specimens: list[Specimen], seed: int, *, participants: int = PAPER_PARTICIPANTS,
                   sessions: int = PAPER_SESSIONS,
                   reference: str = REFERENCE_SPECIMEN, spawn_key: tuple[int, ...] = (),
                   ratings_from: str = defaults.RATINGS_FROM) -> pd.DataFrame:
    """ratings.csv rows: every participant rates every specimen but the reference in each session.

    ``ratings_from`` chooses the source per specimen as :func:`percept` does. Each specimen's draws come from its
    own generator, keyed by ``seed``, ``spawn_key`` and the CRC32 of its name (never Python's salted ``hash``), so
    they do not change when other specimens join the run; the finger model's people (scale and exponent) come
    from one generator keyed by the seed. Only the order of presentation, which has no effect on the ratings,
    depends on the whole set.
    """
    check_ratings_from(ratings_from)
    rows = []
    rated = [s for s in specimens if s.name != reference]
    draws = {}
    people = None
    psych = finger.PSYCHOPHYSICS
    for specimen in rated:
        p = percept(specimen, ratings_from=ratings_from, sessions=sessions)
        rng = _rng(seed, spawn_key, 1, zlib.crc32(specimen.name.encode("utf-8")))
        if p.source == "paper":
            draws[specimen.name] = draw_log_ratings(p.gmean, p.sd, rng, participants=participants,
                                                    sessions=sessions)[0]
            continue
        if people is None:
            people = draw_people(seed, spawn_key, participants)
        log_scale, exponent_factor = people
        session = rng.normal(0.0, psych.session_sd, (participants, sessions))
        log_rating = log_scale[:, None] + psych.exponent * exponent_factor[:, None] * p.log_ratio + session
        draws[specimen.name] = np.exp(log_rating)
    order_rng = _rng(seed, spawn_key, 2)
    session_order = [order_rng.permutation(len(rated)) for _ in range(participants * sessions)]
    for i in range(participants):
        for k in range(sessions):
            for j in session_order[i * sessions + k]:  # specimens were presented in random order
                name = rated[j].name
                rating = max(round(float(draws[name][i, k]), RATING_DECIMALS), 10.0**-RATING_DECIMALS)
                rows.append({"participant": f"P{i + 1:02d}", "session": k + 1, "specimen": name, "rating": rating})
    return pd.DataFrame(rows, columns=["participant", "session", "specimen", "rating"])
