"""Trial-to-trial variation of a real bench, drawn per specimen mount and per exposure.

The paper's protocol (section 3.2) mounts a specimen, takes 1, 2 and 3 N, then remounts: placement, tilt and the
phase of the fingerprint ridges on the grating therefore change per mount, while force setting and light change per
exposure. Defaults are the calibration in docs/simulator.md.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .._util.checks import Real, check
from .optics import Lighting

GRAVITY = 9.80665
MAX_RIDGES = 128  # ridge height errors drawn first per mount; a domain with more ridges draws the rest last


@dataclass(frozen=True)
class BenchNoise:
    force_set_sd_n: float = 0.075  # z-stage: how far the true force lands from the nominal one
    scale_sd_n: float = 0.015  # kitchen scale error on top of its 1 g resolution
    scale_resolution_g: float = 1.0
    position_sd_mm: float = 0.9  # specimen placement along the line
    band_position_sd_px: float = 12.0  # and across it (moves the band up or down in the frame)
    tilt_sd: float = 0.35  # end-to-end relative pressure difference from a slightly tilted specimen
    gain_sd: float = 0.09  # illumination drift
    gradient_sd: float = 0.09
    ripple_sd: float = 0.045  # slow uneven illumination along the line (wavelengths 15-60 mm)
    ripple_count: int = 3
    waviness_sd: float = 0.5  # relative pressure variation from a warped print / uneven pad (wavelengths 6-30 mm)
    waviness_count: int = 4
    magnification_sd: float = 0.022  # camera scale per mount: working distance, focus, where the 45-degree view cuts
    ridge_height_sd_mm: float = 0.025  # fingerprint ridges as cast: height differs ridge to ridge
    ridge_visibility: float = 0.5  # fingerprint ridges seen through the pad where it does not touch (refraction)
    ridge_visibility_sd: float = 0.35  # ... and how much that varies with focus and light, per exposure
    spots_per_mount: float = 12.0  # mean number of dust specks, bubbles and grease marks in the band
    spot_strength: float = 0.75  # typical relative darkening (or brightening) of a spot

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            check(value, Real(0.0), name=f"bench noise {name}", must="a number >= 0")

    def scaled(self, factor: float) -> BenchNoise:
        """All spreads times ``factor`` (the calibration knob); resolutions and counts unchanged."""
        keep = {"scale_resolution_g", "ripple_count", "waviness_count", "spots_per_mount", "ridge_visibility"}
        return BenchNoise(**{k: (v if k in keep else v * factor) for k, v in vars(self).items()})


@dataclass(frozen=True)
class Mount:
    shift_mm: float
    band_shift_px: float
    tilt: float
    pad_phase_mm: float
    magnification: float = 1.0  # true / nominal camera scale
    ridge_offsets_mm: tuple[float, ...] = ()  # height error of the fingerprint ridges that meet this mount
    waviness: tuple[tuple[float, float, float], ...] = ()  # (relative amplitude, wavelength_mm, phase)
    spots: tuple[tuple[float, float, float, float], ...] = ()  # (x_mm, y_mm from band centre, size_mm, strength)

    def local_pressure(self, u_mm: np.ndarray, length_mm: float) -> np.ndarray:
        """Relative local pressure along the specimen from tilt (linear) and waviness, never below 5 %.

        Not normalised: the caller divides by the mean over the specimen (force balance)."""
        rel = np.clip(2.0 * np.asarray(u_mm) / length_mm - 1.0, -1.0, 1.0)
        local = 1.0 + self.tilt * rel
        for amplitude, wavelength_mm, phase in self.waviness:
            local = local + amplitude * np.sin(2.0 * math.pi * u_mm / wavelength_mm + phase)
        return np.maximum(local, 0.05)


@dataclass(frozen=True)
class Exposure:
    force_true_n: float
    force_read_n: float
    lighting: Lighting
    ridge_visibility: float = 0.0


def draw_mount(rng: np.random.Generator, noise: BenchNoise, pad_period_mm: float | None, *,
               ridges: int = MAX_RIDGES) -> Mount:
    """One mount's placement, tilt, warp, spots and (for a ridged pad) the height error of each of ``ridges`` ridges.

    The first ``MAX_RIDGES`` ridge errors are drawn before everything else and any further ones after, so the other
    draws do not depend on how many ridges the contact domain holds (and earlier studies stay byte-identical).
    """
    phase = float(rng.uniform(0.0, pad_period_mm)) if pad_period_mm else 0.0
    mount = Mount(
        shift_mm=float(rng.normal(0.0, noise.position_sd_mm)),
        band_shift_px=float(rng.normal(0.0, noise.band_position_sd_px)),
        tilt=float(rng.normal(0.0, noise.tilt_sd)),
        pad_phase_mm=phase,
        magnification=float(max(1.0 + rng.normal(0.0, noise.magnification_sd), 0.5)),
        ridge_offsets_mm=tuple(float(v) for v in rng.normal(0.0, noise.ridge_height_sd_mm, MAX_RIDGES))
        if pad_period_mm else (),
        waviness=tuple(
            (float(rng.normal(0.0, noise.waviness_sd / math.sqrt(max(noise.waviness_count, 1)))),
             float(rng.uniform(6.0, 30.0)), float(rng.uniform(0, 2 * math.pi)))
            for _ in range(int(noise.waviness_count))
        ),
        spots=tuple(
            (float(rng.uniform(0.0, 60.0)), float(rng.normal(0.0, 2.0)), float(rng.uniform(0.08, 0.8)),
             float(noise.spot_strength * rng.uniform(-0.6, 1.4)))
            for _ in range(int(rng.poisson(noise.spots_per_mount)))
        ),
    )
    if pad_period_mm and ridges > MAX_RIDGES:
        extra = rng.normal(0.0, noise.ridge_height_sd_mm, ridges - MAX_RIDGES)
        mount = replace(mount, ridge_offsets_mm=mount.ridge_offsets_mm + tuple(float(v) for v in extra))
    return mount


def draw_exposure(rng: np.random.Generator, noise: BenchNoise, nominal_force_n: float) -> Exposure:
    true = float(nominal_force_n + rng.normal(0.0, noise.force_set_sd_n))
    true = max(true, 0.2 * nominal_force_n)  # the stage never lifts off
    reading = true + float(rng.normal(0.0, noise.scale_sd_n))
    grams = reading / GRAVITY * 1000.0
    if noise.scale_resolution_g > 0:
        grams = round(grams / noise.scale_resolution_g) * noise.scale_resolution_g
    reading = max(round(grams * GRAVITY / 1000.0, 4), 1e-4)
    ripple = tuple(
        (float(rng.normal(0.0, noise.ripple_sd)), float(rng.uniform(15.0, 60.0)), float(rng.uniform(0, 2 * math.pi)))
        for _ in range(int(noise.ripple_count))
    )
    lighting = Lighting(
        gain=float(max(1.0 + rng.normal(0.0, noise.gain_sd), 0.3)),
        gradient=float(rng.normal(0.0, noise.gradient_sd)),
        ripple=ripple,
    )
    visibility = abs(float(rng.normal(noise.ridge_visibility, noise.ridge_visibility_sd)))
    return Exposure(true, reading, lighting, visibility)
