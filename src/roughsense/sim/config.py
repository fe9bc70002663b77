"""What defines a simulated study (:class:`SimulationConfig`), and the checks of every option before any work.

The numeric options are a table of constraints (:data:`CONSTRAINTS`, in ``_util.checks``' vocabulary), each checked
whether or not the chosen pads use it: study.toml records every one.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace

from .. import defaults
from .._util.checks import POSITIVE, SEED, Described, Integer, check_params
from ..errors import ConfigError
from ..io.protocol import check_force, check_repetitions, nominal_force_label
from ..paper import PAPER_FORCES_N, PAPER_PARTICIPANTS, PAPER_REPETITIONS, PAPER_SESSIONS, PAPER_SPECIMENS
from .bench import BenchNoise
from .limits import pad_problem, panel_problem, specimen_problem
from .optics import Camera
from .pads import PAD_NAMES, Pad, make_pad
from .panel import check_ratings_from
from .specimens import Specimen, expand_specimen_sets, parse_specimen

_MM = Described(POSITIVE, "a positive number of mm")
#: What each numeric option must be (forces and repetitions are the protocol's: ``io.protocol``).
CONSTRAINTS = {
    "fingerprint_period_mm": _MM,
    "ridge_height_mm": _MM,
    "seed": SEED,
    "participants": Described(Integer(2), "a whole number, at least 2"),
    "sessions": Described(Integer(1), "a whole number, at least 1"),
}
#: The command-line name of each option a message names.
OPTION_NAMES = {"fingerprint_period_mm": "--fingerprint-period-mm", "ridge_height_mm": "--ridge-height-mm",
                "seed": "--seed"}


def force_key(force_n: float) -> int:
    """A force's part of the seed keys (micronewtons)."""
    return int(round(force_n * 1e6))


def check_nominal_force_labels(forces_n: Sequence[float]) -> None:
    """Two forces that share an image name or a seed key would overwrite each other's images (or draws)."""
    for what, label in (("image name", nominal_force_label), ("seed key", force_key)):
        seen: dict[object, float] = {}
        for f in forces_n:
            if label(f) in seen:
                other = seen[label(f)]
                if other == f:
                    raise ConfigError(f"--forces-n: {f:g} N is listed twice")
                raise ConfigError(f"--forces-n: {other!r} N and {f!r} N are too close to tell apart (both give the "
                                  f"{what} {label(f)!r}); give forces that differ in their first six significant digits")
            seen[label(f)] = f


@dataclass(frozen=True)
class SimulationConfig:
    """Everything that defines a simulated study. Defaults are the paper's full study (840 images)."""

    pads: tuple[str, ...] = PAD_NAMES
    specimens: tuple[str, ...] = PAPER_SPECIMENS
    forces_n: tuple[float, ...] = PAPER_FORCES_N
    repetitions: int = PAPER_REPETITIONS
    seed: int = defaults.SEED
    fingerprint_period_mm: float = defaults.FINGERPRINT_PERIOD_MM
    ridge_height_mm: float = defaults.RIDGE_HEIGHT_MM
    participants: int = PAPER_PARTICIPANTS
    sessions: int = PAPER_SESSIONS
    name: str = "simulated"
    ratings_from: str = defaults.RATINGS_FROM  # "paper" (presets: the paper's values, else the finger); "physics"
    camera: Camera = field(default_factory=Camera)
    bench: BenchNoise = field(default_factory=BenchNoise)

    def validate(self) -> tuple[list[Pad], list[Specimen]]:
        """Check every option before anything is written; returns the resolved pads and specimens."""
        if not self.pads:
            raise ConfigError("--pads: give at least one pad (smooth, fingerprint)")
        if not self.specimens:
            raise ConfigError("--specimens: give at least one specimen")
        if not self.forces_n:
            raise ConfigError("--forces-n: give at least one force")
        for f in self.forces_n:
            check_force(f, option="--forces-n: every force")
        check_nominal_force_labels(self.forces_n)
        check_ratings_from(self.ratings_from)
        check_repetitions(self.repetitions)
        check_params(asdict(self), CONSTRAINTS, names=OPTION_NAMES)
        pads = [make_pad(p, fingerprint_period_mm=self.fingerprint_period_mm, ridge_height_mm=self.ridge_height_mm)
                for p in self.pads]
        specimens = [parse_specimen(s) for s in expand_specimen_sets(self.specimens)]
        problem = (pad_problem(period_mm=self.fingerprint_period_mm, ridge_height_mm=self.ridge_height_mm,
                               names=("--fingerprint-period-mm", "--ridge-height-mm", "pad modulus"))
                   or next((f"--specimens: {p}" for p in map(specimen_problem, specimens) if p), None)
                   or panel_problem(self.participants, self.sessions))  # what the twin computes (sim.limits)
        if problem:
            raise ConfigError(problem)
        for kind, names in (("pad", [p.name for p in pads]), ("specimen", [s.name for s in specimens])):
            dup = {n for n in names if names.count(n) > 1}
            if dup:
                raise ConfigError(f"{kind} {sorted(dup)[0]!r} is listed twice")
        return pads, specimens

    def toml_table(self) -> dict:
        cam, bench = asdict(self.camera), asdict(self.bench)
        table = {"seed": int(self.seed), "simulator": "roughsense.sim", "pads": list(self.pads),
                 "repetitions": int(self.repetitions), "fingerprint_period_mm": float(self.fingerprint_period_mm),
                 "ridge_height_mm": float(self.ridge_height_mm), "participants": int(self.participants),
                 "sessions": int(self.sessions), "ratings_from": str(self.ratings_from)}
        table.update({f"camera_{k}": v for k, v in cam.items()})
        table.update({f"bench_{k}": v for k, v in bench.items()})
        return table


def ridge_periods(pads: Sequence[Pad]) -> dict[str, float]:
    """The ridge period (mm) of every pad with ridges: study.toml's ``[pads.NAME] ridge_period_mm``, as a rig's user
    writes it for a real pad."""
    return {pad.name: float(pad.period_mm) for pad in pads if pad.has_ridges}


def with_image_size(config: SimulationConfig, width_px: int, height_px: int) -> SimulationConfig:
    """Same study on a smaller frame (tests): the field shrinks, the scale in px/mm stays."""
    return replace(config, camera=replace(config.camera, width_px=int(width_px), height_px=int(height_px)))
