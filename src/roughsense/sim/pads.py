"""The compliant pads: PVC plastisol blocks, smooth or with fingerprint-like ridges parallel to the gratings."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import defaults
from .._util.checks import POSITIVE, AnyOf, Real, check
from ..errors import ConfigError
from ..paper import FINGERPRINT_PAD, SMOOTH_PAD

YOUNG_PA = 0.17e6  # PVC plastisol, paper section 2.2
POISSON = 0.49  # nearly incompressible rubber-like solid; not in the paper, chosen (docs/simulator.md)
RIDGE_EDGE_MM = 0.05  # rounding of the moulded ridge edges (Gaussian sigma); a printed mould has no sharp corners
PAD_NAMES = (SMOOTH_PAD, FINGERPRINT_PAD)


@dataclass(frozen=True)
class Pad:
    """A pad's material and surface relief along the image line (heights in mm, top of the ridges at 0)."""

    name: str
    period_mm: float | None = None  # ridge period; None for the smooth pad
    ridge_height_mm: float = 0.0
    young_pa: float = YOUNG_PA
    poisson: float = POISSON

    def __post_init__(self) -> None:
        check(self.period_mm, AnyOf(POSITIVE, None), name=f"pad {self.name!r}: the ridge period",
              must="a positive number of mm")
        check(self.ridge_height_mm, Real(0.0), name=f"pad {self.name!r}: the ridge height", must=">= 0 mm")

    @property
    def contact_modulus_pa(self) -> float:
        """E* = E / (1 - nu^2): the plane-strain modulus of a half-space against a rigid body."""
        return self.young_pa / (1.0 - self.poisson**2)

    @property
    def has_ridges(self) -> bool:
        return self.period_mm is not None and self.ridge_height_mm > 0

    def height_mm(self, x_mm: np.ndarray, period_mm: float | None = None,
                  ridge_offsets_mm: np.ndarray | None = None) -> np.ndarray:
        """Relief of the pad at ``x_mm``: a square wave of equal ridges and grooves with rounded edges.

        ``period_mm`` overrides the nominal period (the solver may stretch it slightly to fit its periodic domain).
        ``ridge_offsets_mm[i]`` raises ridge i (centred at x = i * period), cycling through the array: cast ridges
        are not all equally high.
        """
        x = np.asarray(x_mm, dtype=float)
        if not self.has_ridges:
            return np.zeros_like(x)
        period = self.period_mm if period_mm is None else period_mm
        # Smoothed square wave from its Fourier series, so the rounding is exact whatever the grid.
        phase = 2.0 * math.pi * x / period
        wave = np.zeros_like(x)
        for m in range(1, 200, 2):
            damping = math.exp(-0.5 * (2.0 * math.pi * m * RIDGE_EDGE_MM / period) ** 2)
            if damping < 1e-6:
                break
            sign = 1.0 if m % 4 == 1 else -1.0
            wave += sign * (4.0 / (math.pi * m)) * damping * np.cos(m * phase)
        # wave ~ +1 on ridges, -1 in grooves
        height = 0.5 * self.ridge_height_mm * (wave - 1.0)
        if ridge_offsets_mm is not None and len(ridge_offsets_mm):
            offsets = np.asarray(ridge_offsets_mm, dtype=float)
            index = np.floor(x / period + 0.5).astype(np.int64) % offsets.size
            height = height + offsets[index]
        return height

    def table_row(self) -> dict:
        return {"pad": self.name, "ridge_period_mm": self.period_mm or 0.0, "ridge_height_mm": self.ridge_height_mm,
                "young_pa": self.young_pa, "poisson": self.poisson}


def make_pad(name: str, *, fingerprint_period_mm: float = defaults.FINGERPRINT_PERIOD_MM,
             ridge_height_mm: float = defaults.RIDGE_HEIGHT_MM) -> Pad:
    """``smooth`` or ``fingerprint`` (with a configurable ridge period and height)."""
    key = name.strip().lower()
    if key == SMOOTH_PAD:
        return Pad(SMOOTH_PAD)
    if key == FINGERPRINT_PAD:
        period = check(fingerprint_period_mm, POSITIVE, name="fingerprint period", must="a positive number of mm")
        height = check(ridge_height_mm, POSITIVE, name="fingerprint ridge height", must="a positive number of mm")
        return Pad(FINGERPRINT_PAD, period_mm=period, ridge_height_mm=height)
    raise ConfigError(f"unknown pad {name!r}; expected one of {', '.join(PAD_NAMES)}")
