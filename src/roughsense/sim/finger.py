"""The simulated finger: how rough a surface feels, from the surface itself (docs/simulator.md, "The finger").

Three stages, each after a published account of macroscopic roughness (spatial coding):

1. **Skin contact.** A fingertip (elastic half-space, E = 0.2 MPa, nu = 0.48, with fingerprint ridges 0.5 mm apart
   and 0.05 mm high running along the grating) is pressed on the specimen's profile at an exploration force; the
   nominal pressure is the force over the finger's contact area, which grows like F^(1/3) (a Hertzian fingertip).
   The periodic contact is solved with the project's own FFT-BEM solver (:mod:`roughsense.sim.contact`). The ridges
   lie at no particular phase to the grating, so the readout is averaged over four ridge phases.
2. **SA1 readout.** The surface pressure is carried to the receptors' depth through the plane-strain half-space
   (Flamant) kernels in Fourier form (Johnson 1985, section 2.8): a pressure harmonic P cos(kx) gives
   sigma_z = -P (1 + kz) e^(-kz), sigma_x = -P (1 - kz) e^(-kz), sigma_y = nu (sigma_x + sigma_z). The SA1 drive is
   the compressive vertical strain there, turned into a saturating drive r = 1 - exp(-strain / saturation_strain)
   (not rectified: tension between contacts lowers it; CHANGELOG.md records the alternatives compared). Roughness
   follows the *spatial variation* of SA1 firing (Connor & Johnson 1992; Blake, Hsiao & Johnson 1997), summarised by
   the SD of r along the line: the root-mean-square
   difference between two receptors, averaged over all their separations, is sqrt(2) times that SD.
3. **Magnitude estimation.** Relative to the reference R3 (felt at the exploration force), a participant reports
   exp(a) * (S / S_R3) ** (b * exp(c)) with S the spatial variation; a ~ N(0, scale_sd^2) is that person's scale,
   c ~ N(-exponent_sd^2 / 2, exponent_sd^2) their exponent (exp(c) averages 1), both drawn once per person
   (:mod:`roughsense.sim.panel`), and each session adds N(0, session_sd^2) in logs. So people disagree most about
   specimens far from the reference, and the spread across people follows from the model, not from a table.

The depth, the saturation strain and the exponent b were fitted to the paper's 13 rated specimens by
``scripts/fit_finger_to_paper.py``, and the three spreads to the paper's SDs; the constants below are that script's output.
This module never reads the paper's tables.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import fft as sfft

from .._util.checks import POSITIVE, check
from ..errors import ConfigError
from ..paper import REFERENCE_SPECIMEN
from . import contact
from .specimens import PRESETS, SPECIMEN_LENGTH_MM, Specimen

# --- output of scripts/fit_finger_to_paper.py (paper's 13 rated specimens; rerun it to reproduce, do not edit by hand).
# Depth and saturation ended on their search bounds (1.0 mm, 3 %): docs/simulator.md, "The finger". ---
FITTED_RECEPTOR_DEPTH_MM = 1.0
FITTED_SATURATION_STRAIN = 0.03
FITTED_EXPONENT = 0.809241
FITTED_SCALE_SD = 0.211604  # log units: participant-to-participant scale
FITTED_EXPONENT_SD = 0.375188  # log units of the exponent: participant-to-participant exponent
FITTED_SESSION_SD = 0.138527  # log units: session-to-session noise of one person
# ---------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Finger:
    """A fingertip and its SA1 readout. Published values except the three marked fitted (docs/simulator.md)."""

    young_pa: float = 0.2e6  # fingertip skin, in-vivo indentation: order 0.1-1 MPa
    poisson: float = 0.48  # nearly incompressible soft tissue
    ridge_period_mm: float = 0.5  # epidermal ridges, adult index finger: ~0.45-0.5 mm
    ridge_height_mm: float = 0.05  # ridge relief
    force_n: float = 1.0  # natural exploration force: of order 0.5-1 N
    contact_area_mm2: float = 100.0  # finger-pad contact area at 1 N; grows like F^(1/3) (Hertz)
    receptor_depth_mm: float = FITTED_RECEPTOR_DEPTH_MM  # fitted, bounded to the SA1 depth range 0.5-1.0 mm
    saturation_strain: float = FITTED_SATURATION_STRAIN  # fitted
    ridge_phases: int = 4
    grid_step_mm: float = 0.01

    def __post_init__(self) -> None:
        for what, value in (("young_pa", self.young_pa), ("ridge_period_mm", self.ridge_period_mm),
                            ("force_n", self.force_n), ("contact_area_mm2", self.contact_area_mm2),
                            ("receptor_depth_mm", self.receptor_depth_mm),
                            ("saturation_strain", self.saturation_strain), ("grid_step_mm", self.grid_step_mm)):
            check(value, POSITIVE, name=f"finger: {what}", must="a positive number")
        if not (0.0 <= self.poisson < 0.5) or not (self.ridge_height_mm >= 0) or self.ridge_phases < 1:
            raise ConfigError("finger: need 0 <= poisson < 0.5, ridge_height_mm >= 0 and ridge_phases >= 1")

    @property
    def contact_modulus_pa(self) -> float:
        return self.young_pa / (1.0 - self.poisson**2)

    def nominal_pressure_pa(self, force_n: float) -> float:
        """Force over the finger-pad contact area, A = A_1N (F / 1 N)^(1/3)."""
        area_mm2 = self.contact_area_mm2 * force_n ** (1.0 / 3.0)
        return force_n / (area_mm2 * 1e-6)


FINGER = Finger()


@dataclass(frozen=True)
class Readout:
    """The SA1 picture of one specimen: firing-rate profiles along x (one per ridge phase) and their variation."""

    x_mm: np.ndarray
    strain: np.ndarray  # (ridge_phases, n): compressive vertical strain at the receptor depth
    rate: np.ndarray  # (ridge_phases, n): saturating SA1 drive, 0..1

    @property
    def spatial_variation(self) -> float:
        return float(self.rate.std(axis=1).mean())


def contact_pressures(specimen: Specimen, finger: Finger = FINGER, force_n: float | None = None
                      ) -> tuple[float, np.ndarray]:
    """Periodic domain length (mm) and contact pressure (Pa) under the finger per ridge phase, (ridge_phases, n)."""
    force_n = finger.force_n if force_n is None else float(force_n)
    if not (math.isfinite(force_n) and force_n > 0):
        raise ConfigError(f"finger force must be a positive number of newtons, got {force_n!r}")
    length, ridge_period = contact.periodic_domain(specimen.period_mm, finger.ridge_period_mm,
                                                   max_length_mm=SPECIMEN_LENGTH_MM)
    n = contact.grid_points(length, finger.grid_step_mm)
    x = np.arange(n) * (length / n)
    base = specimen.height_mm(x)
    pressure = finger.nominal_pressure_pa(force_n)
    out = np.empty((finger.ridge_phases, n))
    for i in range(finger.ridge_phases):
        # smooth ridges (their fundamental only): crests at 0, furrows at -ridge_height
        shift = i * ridge_period / finger.ridge_phases
        ridges = 0.5 * finger.ridge_height_mm * (np.cos(2.0 * math.pi * (x - shift) / ridge_period) - 1.0)
        try:
            solution = contact.solve_periodic(base + ridges, length, pressure, finger.contact_modulus_pa, tol=1e-6)
        except contact.ContactNotConverged as exc:
            raise ConfigError(f"finger on specimen {specimen.name!r} at {force_n:g} N: {exc.message}") from None
        out[i] = solution.pressure_pa
    return length, out


def subsurface_stress(pressure_pa: np.ndarray, length_mm: float, depth_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """(sigma_x, sigma_z) in Pa at ``depth_mm`` under a periodic surface pressure on a plane-strain half-space.

    Each pressure harmonic decays with depth as the Flamant kernel integrated over the surface gives (Johnson 1985,
    section 2.8, a cosine load); the mean pressure gives sigma_x = sigma_z = -p, the long-wave limit.
    """
    p = np.asarray(pressure_pa, dtype=float)
    n = p.shape[-1]
    k = 2.0 * math.pi * sfft.rfftfreq(n, d=length_mm / n)
    kz = k * depth_mm
    decay = np.exp(-kz)
    spectrum = sfft.rfft(p, axis=-1)
    sigma_z = -sfft.irfft(spectrum * (1.0 + kz) * decay, n, axis=-1)
    sigma_x = -sfft.irfft(spectrum * (1.0 - kz) * decay, n, axis=-1)
    return sigma_x, sigma_z


def subsurface_strain(pressure_pa: np.ndarray, length_mm: float, depth_mm: float, young_pa: float,
                      poisson: float) -> np.ndarray:
    """Compressive vertical strain (positive in compression) at ``depth_mm``, plane strain (sigma_y = nu (sx + sz))."""
    sigma_x, sigma_z = subsurface_stress(pressure_pa, length_mm, depth_mm)
    sigma_y = poisson * (sigma_x + sigma_z)
    return -(sigma_z - poisson * (sigma_x + sigma_y)) / young_pa


def readout(specimen: Specimen, *, finger: Finger = FINGER, force_n: float | None = None) -> Readout:
    """The SA1 firing pattern under the finger pressed on ``specimen`` (at ``finger.force_n`` by default)."""
    length, pressure = contact_pressures(specimen, finger, force_n)
    strain = subsurface_strain(pressure, length, finger.receptor_depth_mm, finger.young_pa, finger.poisson)
    rate = sa1_rate(strain, finger.saturation_strain)
    x = np.arange(pressure.shape[1]) * (length / pressure.shape[1])
    return Readout(x, strain, rate)


def sa1_rate(strain: np.ndarray, saturation_strain: float) -> np.ndarray:
    """Saturating SA1 drive (0 at no strain, 1 - 1/e at the saturation strain); tension drives it below 0."""
    return 1.0 - np.exp(-np.asarray(strain) / saturation_strain)


@lru_cache(maxsize=4096)
def spatial_variation(specimen: Specimen, *, finger: Finger = FINGER, force_n: float | None = None) -> float:
    """S: the SD of SA1 firing along the line, averaged over ridge phases (cached; specimens are immutable)."""
    return readout(specimen, finger=finger, force_n=force_n).spatial_variation


@dataclass(frozen=True)
class Psychophysics:
    """Magnitude estimation relative to R3: the population exponent and the people's spreads (log units)."""

    exponent: float = FITTED_EXPONENT
    scale_sd: float = FITTED_SCALE_SD
    exponent_sd: float = FITTED_EXPONENT_SD
    session_sd: float = FITTED_SESSION_SD

    def log_sd_of_medians(self, log_ratio: float, sessions: int = 3) -> float:
        """SD across participants of log(median over sessions): scale, exponent (delta method), session terms."""
        session_var = _median_variance(sessions) * self.session_sd**2
        slope = self.exponent * self.exponent_sd * log_ratio
        return math.sqrt(self.scale_sd**2 + slope**2 + session_var)


PSYCHOPHYSICS = Psychophysics()


def _median_variance(sessions: int) -> float:
    """Variance of the median of ``sessions`` standard normals (exact for 1 and 2; order statistics for 3)."""
    return {1: 1.0, 2: 0.5, 3: 0.4487}.get(sessions, math.pi / (2 * sessions))


def log_ratio(specimen: Specimen, *, finger: Finger = FINGER, force_n: float | None = None) -> float:
    """log(S / S_R3): the specimen's spatial variation relative to the reference felt at the exploration force."""
    reference = spatial_variation(PRESETS[REFERENCE_SPECIMEN], finger=finger)
    return math.log(spatial_variation(specimen, finger=finger, force_n=force_n) / reference)


def magnitude(specimen: Specimen, *, finger: Finger = FINGER, psychophysics: Psychophysics = PSYCHOPHYSICS,
              force_n: float | None = None) -> float:
    """The typical participant's magnitude estimate (R3 = 1): (S / S_R3) ** exponent."""
    return math.exp(psychophysics.exponent * log_ratio(specimen, finger=finger, force_n=force_n))

