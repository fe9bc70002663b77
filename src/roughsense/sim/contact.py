"""Periodic line contact of a rigid profile on an elastic half-space (plane strain), by FFT-BEM.

The gratings and the fingerprint ridges run along y, so along the image line the problem is a 1D periodic
contact: surface displacement u_k = 2 p_k / (E* |k|) (Johnson 1985, section 13.2), solved at fixed mean pressure
with the constrained conjugate gradient of Polonsky & Keer (Wear 231, 1999). It is our own vectorised solver
(no per-call object set-up), tested against ContactMechanics and against Westergaard's and Hertz's solutions.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
from scipy import fft as sfft

from ..errors import ConfigError

NOMINAL_AREA_MM2 = 50.0 * 10.0  # specimen footprint: p = F / (50 mm x 10 mm)
GRID_STEP_MM = 0.005  # solver resolution: ~6 points per camera pixel (34.9 px/mm)


def nominal_pressure_pa(force_n: float) -> float:
    return force_n / (NOMINAL_AREA_MM2 * 1e-6)


class ContactNotConverged(ConfigError):
    """The solver ran out of iterations: the pad and profile chosen are beyond what it resolves."""


@dataclass(frozen=True)
class ContactSolution:
    """Pressure (Pa) and gap (mm) on the periodic grid ``x_mm``.

    ``gap_mm`` is clean (0 in contact, >= 0 elsewhere). The solver's own state is kept beside it so that tests can
    check the physics rather than the clean-up: ``raw_gap_mm`` is the gap before clipping (~0 in contact, and no
    penetration, >= 0 up to the tolerance, outside), ``balance`` the mean pressure over the target before the last
    rescaling (1 when the converged step itself balances the load), ``change`` the last relative pressure change.
    """

    x_mm: np.ndarray
    pressure_pa: np.ndarray
    gap_mm: np.ndarray
    iterations: int
    raw_gap_mm: np.ndarray | None = None
    balance: float = 1.0
    change: float = 0.0

    @property
    def contact(self) -> np.ndarray:
        return self.pressure_pa > 0

    @property
    def contact_fraction(self) -> float:
        return float(np.mean(self.contact))


def solve_periodic(height_mm: np.ndarray, length_mm: float, mean_pressure_pa: float, contact_modulus_pa: float,
                   *, tol: float = 1e-9, max_iter: int = 20000, initial_pressure_pa: np.ndarray | None = None
                   ) -> ContactSolution:
    """Press a rigid periodic profile (heights in mm, peaks up) onto a half-space at a mean pressure.

    Returns the contact pressure and the gap between the deformed pad and the profile. Raises
    :class:`ContactNotConverged` if the relative pressure change is still above ``tol`` after ``max_iter`` steps.
    ``initial_pressure_pa`` starts the iteration from a nearby solution (the same profile at another load, rescaled
    to this one): the converged contact is the same, reached in fewer steps.
    """
    h = np.asarray(height_mm, dtype=float)
    n = h.size
    if n < 4 or not (length_mm > 0 and mean_pressure_pa > 0 and contact_modulus_pa > 0):
        raise ConfigError("contact needs >= 4 grid points and positive length, pressure and modulus")
    k = 2.0 * math.pi * sfft.rfftfreq(n, d=length_mm / n)
    compliance = np.zeros_like(k)
    compliance[1:] = 2.0 / (contact_modulus_pa * k[1:])  # mm of displacement per Pa of pressure amplitude

    def displacement(p: np.ndarray) -> np.ndarray:
        return sfft.irfft(sfft.rfft(p) * compliance, n)

    s = h - h.max()
    p = np.full(n, float(mean_pressure_pa))
    if initial_pressure_pa is not None:
        start = np.maximum(np.asarray(initial_pressure_pa, dtype=float), 0.0)
        if start.shape == (n,) and start.sum() > 0:
            p = start * (mean_pressure_pa / start.mean())
    t = np.zeros(n)
    g_old = 1.0
    delta = 0.0
    it = 0
    balance, change, converged = 1.0, math.inf, False
    for it in range(1, max_iter + 1):
        gap = displacement(p) - s
        inside = p > 0
        gap -= gap[inside].mean()
        g_norm = float(np.dot(gap[inside], gap[inside]))
        t = np.where(inside, gap + delta * (g_norm / g_old if g_old > 0 else 0.0) * t, 0.0)  # 0: start was the answer
        g_old = g_norm
        r = displacement(t)
        r -= r[inside].mean()
        denom = float(np.dot(r[inside], t[inside]))
        tau = float(np.dot(gap[inside], t[inside])) / denom if denom != 0 else 0.0
        p_prev = p
        p = np.where(inside, p - tau * t, p)
        p[p < 0] = 0.0
        overlap = (p == 0) & (gap < 0)
        if overlap.any():
            delta = 0.0
            p[overlap] -= tau * gap[overlap]
        else:
            delta = 1.0
        total = p.mean()
        if total <= 0:
            p = np.full(n, float(mean_pressure_pa))
            continue
        balance = float(total / mean_pressure_pa)
        p *= mean_pressure_pa / total
        change = float(np.abs(p - p_prev).sum()) / (n * mean_pressure_pa)
        if change < tol and it > 2:
            converged = True
            break
    if not converged:
        raise ContactNotConverged(f"the contact solver did not converge in {max_iter} iterations "
                                  f"(relative pressure change {change:.1e}, tolerance {tol:.0e})")
    raw = displacement(p) - s
    inside = p > 0
    raw -= raw[inside].mean() if inside.any() else raw.min()
    gap = np.where(inside, 0.0, np.maximum(raw, 0.0))
    x = np.arange(n) * (length_mm / n)
    return ContactSolution(x, p, gap, it, raw_gap_mm=raw, balance=balance, change=change)


def periodic_domain(specimen_period_mm: float, pad_period_mm: float | None, *, max_length_mm: float = 50.0
                    ) -> tuple[float, float | None]:
    """Smallest length holding whole periods of both specimen and pad, and the pad period used.

    Incommensurate periods (a 0.7 mm pad on a 2.5 mm grating) repeat only after a long stretch; beyond
    ``max_length_mm`` the pad period is stretched to fit a whole number of ridges (by well under 1 %).
    """
    if pad_period_mm is None:
        return specimen_period_mm, None
    ratio = Fraction(pad_period_mm / specimen_period_mm).limit_denominator(1000)
    # L = a * specimen = b * pad  with a/b = pad/specimen = ratio  ->  a = ratio.numerator
    length = specimen_period_mm * ratio.numerator
    if ratio.numerator == 0 or length > max_length_mm + 1e-9 or abs(float(ratio) * specimen_period_mm - pad_period_mm) > 1e-9:
        repeats = max(1, int(max_length_mm // specimen_period_mm))
        length = specimen_period_mm * repeats
    ridges = max(1, round(length / pad_period_mm))
    return length, length / ridges


def grid_points(length_mm: float, step_mm: float = GRID_STEP_MM) -> int:
    return int(sfft.next_fast_len(max(64, math.ceil(length_mm / step_mm)), real=True))
