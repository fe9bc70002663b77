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
    return solve_periodic_many(height_mm, length_mm, [mean_pressure_pa], contact_modulus_pa, tol=tol,
                               max_iter=max_iter, initial_pressure_pa=initial_pressure_pa)[0]


def solve_periodic_many(height_mm: np.ndarray, length_mm: float, mean_pressures_pa, contact_modulus_pa: float,
                        *, tol: float = 1e-9, max_iter: int = 20000, initial_pressure_pa: np.ndarray | None = None
                        ) -> list[ContactSolution]:
    """:func:`solve_periodic` for one profile at several mean pressures, all levels in one iteration.

    Each level (a row) follows exactly the single-level iteration and leaves the batch once it has converged; the
    rows only share the calls. At the grid sizes of a grating (400-2000 points) a step's cost is mostly per call,
    not per point, so five levels solved together cost about what two solved one after another do (BENCHMARKS.md).
    ``initial_pressure_pa`` (one profile) starts every level, rescaled to its load.
    """
    h = np.asarray(height_mm, dtype=float)
    levels = np.asarray(mean_pressures_pa, dtype=float).ravel()
    n = h.size
    if n < 4 or not (length_mm > 0 and contact_modulus_pa > 0) or levels.size == 0 \
            or not np.all(np.isfinite(levels) & (levels > 0)):
        raise ConfigError("contact needs >= 4 grid points and positive length, pressure and modulus")
    k = 2.0 * math.pi * sfft.rfftfreq(n, d=length_mm / n)
    compliance = np.zeros_like(k)
    # An extreme modulus overflows the arithmetic: caught here as one error, not numpy warnings and 20000 NaN steps.
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        compliance[1:] = 2.0 / (contact_modulus_pa * k[1:])  # mm of displacement per Pa of pressure amplitude
        s = h - h.max()
        batch = _PressureBatch(levels, s, compliance, initial_pressure_pa)
        for it in range(1, max_iter + 1):
            if batch.step(it, tol):
                break
            if not np.isfinite(batch.change[batch.rows]).all():
                raise ContactNotConverged(f"the contact solver's numbers overflowed at iteration {it}: a contact "
                                          f"modulus of {contact_modulus_pa:g} Pa is outside what it can compute")
    if batch.rows.size:
        worst = float(batch.change[batch.rows].max())
        raise ContactNotConverged(f"the contact solver did not converge in {max_iter} iterations "
                                  f"(relative pressure change {worst:.1e}, tolerance {tol:.0e})")
    return _solutions(batch, length_mm)


def _displacement(p: np.ndarray, compliance: np.ndarray, n: int) -> np.ndarray:
    """Surface displacement (mm) of the half-space under periodic pressure rows ``p`` (Pa), by FFT."""
    return sfft.irfft(sfft.rfft(p, axis=-1) * compliance, n, axis=-1)


def _row_mean(values: np.ndarray, mask: np.ndarray, count: np.ndarray) -> np.ndarray:
    return np.where(mask, values, 0.0).sum(axis=1) / count


class _PressureBatch:
    """The Polonsky-Keer constrained conjugate-gradient state of every level still iterating, one row a level.

    A row that converges is recorded in ``done`` and leaves the arrays, so the rows left share each call.
    """

    def __init__(self, levels: np.ndarray, s: np.ndarray, compliance: np.ndarray,
                 initial_pressure_pa: np.ndarray | None) -> None:
        n = s.size
        self.n, self.s, self.compliance = n, s, compliance
        self.target = levels.copy()  # the mean pressure of each row still iterating
        self.p = np.repeat(self.target[:, None], n, axis=1)
        if initial_pressure_pa is not None:
            start = np.maximum(np.asarray(initial_pressure_pa, dtype=float), 0.0)
            if start.shape == (n,) and start.sum() > 0:
                self.p = start[None, :] * (self.target / start.mean())[:, None]
        self.t = np.zeros_like(self.p)
        self.g_old = np.ones(levels.size)
        self.delta = np.zeros(levels.size)
        self.rows = np.arange(levels.size)  # which level each working row is
        self.balance = np.ones(levels.size)
        self.change = np.full(levels.size, math.inf)
        self.done: dict[int, tuple[np.ndarray, int, float, float]] = {}

    def step(self, it: int, tol: float) -> bool:
        """One conjugate-gradient step of every row; True once no row is left."""
        n, p, t = self.n, self.p, self.t
        gap = _displacement(p, self.compliance, n) - self.s
        inside = p > 0
        count = inside.sum(axis=1)
        gap -= _row_mean(gap, inside, count)[:, None]
        g_norm = np.einsum("ij,ij->i", gap, np.where(inside, gap, 0.0))
        ratio = np.divide(g_norm, self.g_old, out=np.zeros_like(g_norm), where=self.g_old > 0)  # 0: start was the answer
        t = np.where(inside, gap + (self.delta * ratio)[:, None] * t, 0.0)
        self.g_old = g_norm
        r = _displacement(t, self.compliance, n)
        r -= _row_mean(r, inside, count)[:, None]
        denom = np.einsum("ij,ij->i", r, t)  # t is 0 outside the contact
        tau = np.divide(np.einsum("ij,ij->i", gap, t), denom, out=np.zeros_like(denom), where=denom != 0)
        p_prev = p
        p = p - tau[:, None] * t
        np.maximum(p, 0.0, out=p)
        overlap = (p == 0) & (gap < 0)
        lifted = overlap.any(axis=1)
        if lifted.any():
            p -= np.where(overlap, tau[:, None] * gap, 0.0)
        self.delta = np.where(lifted, 0.0, 1.0)
        self.p, self.t = p, t
        step, lost = self._keep_the_load(p_prev)
        finished = ~lost & (step < tol) & (it > 2)
        if finished.any():
            self._retire(finished, it, step)
        return self.rows.size == 0

    def _keep_the_load(self, p_prev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rescale each row to its mean pressure; returns the relative change of the step and the rows restarted."""
        p, target, rows = self.p, self.target, self.rows
        total = p.mean(axis=1)
        lost = total <= 0  # every point let go: start that level again from uniform pressure
        if lost.any():
            p[lost] = target[lost, None]
            total = np.where(lost, target, total)
        self.balance[rows] = np.where(lost, self.balance[rows], total / target)
        p *= (target / total)[:, None]
        step = np.abs(p - p_prev).sum(axis=1) / (self.n * target)
        self.change[rows] = np.where(lost, self.change[rows], step)
        return step, lost

    def _retire(self, finished: np.ndarray, it: int, step: np.ndarray) -> None:
        for i in np.flatnonzero(finished):
            self.done[int(self.rows[i])] = (self.p[i], it, float(self.balance[self.rows[i]]), float(step[i]))
        keep = ~finished
        self.p, self.t, self.g_old, self.delta = self.p[keep], self.t[keep], self.g_old[keep], self.delta[keep]
        self.target, self.rows = self.target[keep], self.rows[keep]


def _solutions(batch: _PressureBatch, length_mm: float) -> list[ContactSolution]:
    """Each level's converged pressure, its gap (clean and raw) and the solver's record, in level order."""
    n, done = batch.n, batch.done
    pressure = np.stack([done[i][0] for i in range(len(done))])
    raw = _displacement(pressure, batch.compliance, n) - batch.s
    x = np.arange(n) * (length_mm / n)
    solutions = []
    for i in range(len(done)):
        p_i, raw_i = pressure[i], raw[i]
        inside = p_i > 0
        raw_i -= raw_i[inside].mean() if inside.any() else raw_i.min()
        gap = np.where(inside, 0.0, np.maximum(raw_i, 0.0))
        solutions.append(ContactSolution(x, p_i, gap, done[i][1], raw_gap_mm=raw_i, balance=done[i][2],
                                         change=done[i][3]))
    return solutions


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
