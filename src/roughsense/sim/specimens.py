"""Rigid grating specimens: the paper's fourteen presets and user specs for new ones.

Heights are in mm along the image line (x), ridges along y, with the highest point at 0 and valleys negative,
so a profile can be added to the pad's relief and handed to the contact solver as one composite surface.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._util.checks import POSITIVE, check
from ..errors import ConfigError
from ..io.names import NAME_RULE, is_safe_name
from ..io.numbers import NumberError, parse_number
from ..paper import PAPER_SPECIMENS, PAPER_WAVELENGTHS_MM

SPECIMEN_LENGTH_MM = 50.0
SPECIMEN_WIDTH_MM = 10.0
DEFAULT_GROOVE_DEPTH_MM = 1.0  # not in the paper, chosen (docs/simulator.md); deep enough that the pad never reaches the floor
SHAPES = ("rectangular", "circular", "sinusoidal", "random")


@dataclass(frozen=True)
class Specimen:
    """One grating. ``wavelength_mm`` is the period (for random gratings: the correlation length)."""

    name: str
    shape: str
    wavelength_mm: float
    groove_depth_mm: float = float("nan")  # rectangular: groove depth
    ridge_width_mm: float = float("nan")  # rectangular: land width
    diameter_mm: float = float("nan")  # circular: cylinder diameter (= wavelength)
    amplitude_mm: float = float("nan")  # sinusoidal: amplitude; random: rms height
    seed: int = 0  # random: seed of its (fixed, printed-once) profile
    preset: bool = False

    def __post_init__(self) -> None:
        if self.shape not in SHAPES:
            raise ConfigError(f"unknown specimen shape {self.shape!r}; expected one of {', '.join(SHAPES)}")
        _positive("wavelength", self.wavelength_mm, self.name)
        if self.shape == "rectangular":
            _positive("groove depth", self.groove_depth_mm, self.name)
            _positive("ridge width", self.ridge_width_mm, self.name)
            if self.ridge_width_mm >= self.wavelength_mm:
                raise ConfigError(f"specimen {self.name!r}: ridge width must be smaller than the wavelength")
        if self.shape in ("sinusoidal", "random"):
            _positive("amplitude", self.amplitude_mm, self.name)

    @property
    def period_mm(self) -> float:
        """Length after which the profile repeats (random gratings repeat once per specimen)."""
        return SPECIMEN_LENGTH_MM if self.shape == "random" else self.wavelength_mm

    @property
    def groove_width_mm(self) -> float:
        """Width of the valley a fingertip can sink into: the groove, or half a period for rounded profiles."""
        if self.shape == "rectangular":
            return self.wavelength_mm - self.ridge_width_mm
        return self.wavelength_mm / 2.0

    def height_mm(self, x_mm: np.ndarray) -> np.ndarray:
        """Surface height at ``x_mm`` (periodic with ``period_mm``); 0 is the top of the ridges."""
        x = np.mod(np.asarray(x_mm, dtype=float), self.period_mm)
        lam = self.wavelength_mm
        if self.shape == "rectangular":
            # land centred at lam/2 so that a period starts and ends in a groove
            land = np.abs(x - lam / 2.0) <= self.ridge_width_mm / 2.0
            return np.where(land, 0.0, -self.groove_depth_mm)
        if self.shape == "circular":
            radius = lam / 2.0
            u = x - lam / 2.0
            return np.sqrt(np.maximum(radius * radius - u * u, 0.0)) - radius
        if self.shape == "sinusoidal":
            return self.amplitude_mm * (np.cos(2.0 * math.pi * (x - lam / 2.0) / lam) - 1.0)
        return self._random_height(x)

    def _random_height(self, x: np.ndarray) -> np.ndarray:
        # Gaussian random profile with Gaussian autocorrelation exp(-(x/l)^2), l = `wavelength_mm`, periodic over the
        # specimen. Its power spectrum is proportional to exp(-(pi k l)^2) (k in cycles/mm), so the amplitude of each
        # Fourier coefficient is the square root of that.
        n = 4096
        length = SPECIMEN_LENGTH_MM
        rng = np.random.default_rng(self.seed)
        k = np.fft.rfftfreq(n, d=length / n)
        spectrum = np.exp(-((math.pi * k * self.wavelength_mm) ** 2) / 2.0)
        spectrum[0] = 0.0
        coeff = spectrum * (rng.standard_normal(k.size) + 1j * rng.standard_normal(k.size))
        profile = np.fft.irfft(coeff, n)
        profile *= self.amplitude_mm / max(profile.std(), 1e-300)
        profile -= profile.max()
        grid = np.arange(n + 1) * length / n
        return np.interp(x, grid, np.append(profile, profile[0]))

    def table_row(self) -> dict:
        """The specimens.csv row: shape, wavelength and every geometry column (blank where it does not apply)."""
        return {
            "specimen": self.name,
            "shape": self.shape,
            "wavelength_mm": self.wavelength_mm,
            "groove_width_mm": self.groove_width_mm,
            "groove_depth_mm": self.groove_depth_mm,
            "ridge_width_mm": self.ridge_width_mm,
            "diameter_mm": self.diameter_mm,
            "amplitude_mm": self.amplitude_mm,
            "length_mm": SPECIMEN_LENGTH_MM,
            "width_mm": SPECIMEN_WIDTH_MM,
        }


def _positive(what: str, value: float, name: str) -> None:
    check(value, POSITIVE, name=f"specimen {name!r}: {what}", must="a positive number of mm")


def rectangular(wavelength_mm: float, *, groove_depth_mm: float = DEFAULT_GROOVE_DEPTH_MM,
                ridge_width_mm: float | None = None, name: str | None = None) -> Specimen:
    _positive("wavelength", wavelength_mm, name or "rect")
    ridge = wavelength_mm / 2.0 if ridge_width_mm is None else ridge_width_mm
    return Specimen(name or f"rect:{wavelength_mm:g}", "rectangular", float(wavelength_mm),
                    groove_depth_mm=float(groove_depth_mm), ridge_width_mm=float(ridge))


def circular(diameter_mm: float, *, name: str | None = None) -> Specimen:
    _positive("diameter", diameter_mm, name or "circ")
    return Specimen(name or f"circ:{diameter_mm:g}", "circular", float(diameter_mm), diameter_mm=float(diameter_mm))


def sinusoidal(wavelength_mm: float, amplitude_mm: float, *, name: str | None = None) -> Specimen:
    return Specimen(name or f"sin:{wavelength_mm:g}:{amplitude_mm:g}", "sinusoidal", float(wavelength_mm),
                    amplitude_mm=float(amplitude_mm))


def random_grating(correlation_mm: float, rms_mm: float, *, seed: int = 0, name: str | None = None) -> Specimen:
    return Specimen(name or f"rand:{correlation_mm:g}:{rms_mm:g}:{seed}", "random", float(correlation_mm),
                    amplitude_mm=float(rms_mm), seed=int(seed))


def _preset_table() -> dict[str, Specimen]:
    table = {}
    for lam in PAPER_WAVELENGTHS_MM:
        label = f"{lam:g}"
        table[f"R{label}"] = Specimen(f"R{label}", "rectangular", lam, groove_depth_mm=DEFAULT_GROOVE_DEPTH_MM,
                                      ridge_width_mm=lam / 2.0, preset=True)
        table[f"C{label}"] = Specimen(f"C{label}", "circular", lam, diameter_mm=lam, preset=True)
    return table


PRESETS: dict[str, Specimen] = _preset_table()

#: The periods and land fractions of the gratings that tell period from groove width: at each period a narrow and
#: a wide land (groove = period - land), so the groove varies at a fixed period, which the paper's half-land
#: rectangles never do. Depth: the paper's rectangles' (DEFAULT_GROOVE_DEPTH_MM).
GROOVE_PERIODS_MM = (2.0, 3.0, 4.0, 5.0)
GROOVE_LAND_FRACTIONS = (0.3, 0.7)
GROOVE_SPECS = tuple(f"rect:{period:g}:{DEFAULT_GROOVE_DEPTH_MM:g}:{round(fraction * period, 6):g}"
                     for period in GROOVE_PERIODS_MM for fraction in GROOVE_LAND_FRACTIONS)
#: Named specimen sets (name -> specs), accepted wherever a list of specimens is (``simulate --specimens``, a sweep
#: file's ``specimens``, ``--study builtin:SET``): ``paper`` is the paper's 14; ``paper+grooves`` adds rectangles
#: whose land differs from their groove at the paper's periods, so that a model can tell period from groove width.
SPECIMEN_SETS: dict[str, tuple[str, ...]] = {
    "paper": PAPER_SPECIMENS,
    "paper+grooves": PAPER_SPECIMENS + GROOVE_SPECS,
    "rectangular": tuple(s for s in PAPER_SPECIMENS if s.startswith("R")),
    "circular": tuple(s for s in PAPER_SPECIMENS if s.startswith("C")),
}
PAPER_SET = "paper"

SPEC_HELP = (
    "A preset (R2, R2.5, ..., R5, C2, ..., C5), a set (" + ", ".join(SPECIMEN_SETS) + ") or a spec: "
    "rect:WAVELENGTH[:DEPTH[:RIDGE_WIDTH]], "
    "circ:DIAMETER, sin:WAVELENGTH:AMPLITUDE, rand:CORRELATION_LENGTH:RMS[:SEED] (all in mm)."
)


def expand_specimen_sets(texts) -> tuple[str, ...]:
    """Specimen texts with every set name (:data:`SPECIMEN_SETS`) replaced by its specs, in order."""
    expanded: list[str] = []
    for text in texts:
        key = text.strip().lower()
        expanded.extend(SPECIMEN_SETS.get(key, (text,)))
    return tuple(expanded)


def check_specimen_set(name: str, *, option: str) -> str:
    """``name`` as a set's key (lower case), or a ConfigError naming ``option`` and the sets there are."""
    key = name.strip().lower()
    if key not in SPECIMEN_SETS:
        raise ConfigError(f"{option}: unknown specimen set {name!r} (expected one of {', '.join(SPECIMEN_SETS)})")
    return key


def parse_specimen(text: str) -> Specimen:
    """A preset name or a spec like ``sin:3.0:0.5`` (see :data:`SPEC_HELP`)."""
    text = text.strip()
    if text in PRESETS:
        return PRESETS[text]
    upper = text.upper()
    if upper in PRESETS:
        return PRESETS[upper]
    kind, _, rest = text.partition(":")
    kind = kind.lower()
    arity = {"rect": (1, 3), "circ": (1, 1), "sin": (2, 2), "rand": (2, 3)}
    if not rest or kind not in arity:
        raise ConfigError(f"unknown specimen {text!r}. {SPEC_HELP}")
    parts = rest.split(":")
    lo, hi = arity[kind]
    if not lo <= len(parts) <= hi:
        raise ConfigError(f"specimen {text!r}: {kind} takes {lo}" + (f" to {hi}" if hi > lo else "") + f" numbers. {SPEC_HELP}")
    numbers = [_spec_number(text, part, seed=kind == "rand" and k == 2) for k, part in enumerate(parts)]
    # The spec becomes the specimen's name in the study folder and in image names: ':' is not a name character.
    text = "_".join([text.partition(":")[0].strip(), *(part.strip() for part in parts)])
    if not is_safe_name(text):
        raise ConfigError(f"specimen {text!r}: a spec's numbers must give a valid name ({NAME_RULE})")
    for value in numbers[:2] if kind != "rect" else numbers:
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(f"specimen {text!r}: every size must be a positive number of mm, got {value:g}")
    if kind == "rect":
        depth = numbers[1] if len(numbers) > 1 else DEFAULT_GROOVE_DEPTH_MM
        ridge = numbers[2] if len(numbers) > 2 else None
        return rectangular(numbers[0], groove_depth_mm=depth, ridge_width_mm=ridge, name=text)
    if kind == "circ":
        return circular(numbers[0], name=text)
    if kind == "sin":
        return sinusoidal(numbers[0], numbers[1], name=text)
    return random_grating(numbers[0], numbers[1], seed=int(numbers[2]) if len(numbers) > 2 else 0, name=text)


def _spec_number(spec: str, part: str, *, seed: bool) -> float | int:
    """One number of a spec by the one number parser (``1_5`` is not 15 mm); a seed is whole and bounded."""
    try:
        return parse_number(part, quantity="seed") if seed else float(parse_number(part))
    except NumberError as exc:
        if not seed:
            raise ConfigError(f"specimen {spec!r}: {exc.message}. {SPEC_HELP}") from None
        message = exc.message
        raise ConfigError(f"specimen {spec!r}: the seed {'is ' if message.startswith('not') else ''}{message}") from None
