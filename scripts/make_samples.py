"""Write the synthetic sample images shipped in src/roughsense/data/samples/ (run: make samples).

They are clearly not real data: each is a smoothed rectangular grating of a known wavelength plus the
pad's 1 mm fingerprint ridges, drawn as a bright horizontal contact band on a dark, flat background.
One image per format/depth/colour case the sensor must read, kept small (flat regions compress well).
Deterministic: no random draws, so rerunning reproduces the same bytes for the lossless formats.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter1d

PX_PER_MM = 34.9
SAMPLES = Path(__file__).resolve().parents[1] / "src" / "roughsense" / "data" / "samples"

# name, width_px, height_px, wavelength_mm, colour, bits
SPECS = [
    ("synthetic_grating_3mm_gray8_1920x1080.png", 1920, 1080, 3.0, False, 8),
    ("synthetic_grating_2mm_rgb8.jpg", 960, 240, 2.0, True, 8),
    ("synthetic_grating_2.5mm_gray8.bmp", 640, 200, 2.5, False, 8),
    ("synthetic_grating_4mm_gray16.tif", 640, 200, 4.0, False, 16),
    ("synthetic_grating_5mm_rgb16.png", 640, 200, 5.0, True, 16),
]

README = """Synthetic sample images -- NOT real sensor data.

Written by scripts/make_samples.py: a smoothed rectangular grating of the wavelength in the file name
plus 1 mm fingerprint ridges (a weaker peak at 1 mm^-1), drawn as a bright contact band across the
middle of a dark, flat frame. The scale is the paper's, 34.9 px/mm (the default --px-per-mm).

Only synthetic_grating_3mm_gray8_1920x1080.png is a full 1920x1080 frame, so only it works with the
default --roi center (1900 x 150 px centred). The others are smaller, so use --roi auto (the 150-row
band with the strongest horizontal texture, full width) or an explicit --roi X,Y,W,H. These copy
them out of the installed package (into ./samples) and read all five:

    roughsense example samples --out samples
    roughsense features --roi auto --out features.csv samples/synthetic_grating_*

(In a clone they are also in src/roughsense/data/samples/.)

Formats covered: PNG 8-bit gray, PNG 16-bit RGB, JPEG 8-bit RGB, TIFF 16-bit gray, BMP 8-bit gray.
"""


def render(width_px: int, height_px: int, wavelength_mm: float, band_rows: int = 180) -> np.ndarray:
    """Gray level in [0, 1]: flat background, and a contact band whose brightness follows the grating."""
    x_mm = np.arange(width_px) / PX_PER_MM
    lands = (np.mod(x_mm, wavelength_mm) < wavelength_mm / 2).astype(float)
    lands = gaussian_filter1d(lands, sigma=0.15 * PX_PER_MM, mode="wrap")
    ridges = 0.5 + 0.5 * np.cos(2 * np.pi * x_mm / 1.0)
    profile = 0.7 * lands + 0.3 * lands * ridges
    rows = np.arange(height_px) - (height_px - 1) / 2
    band = np.clip((band_rows / 2 - np.abs(rows)) / 12.0, 0.0, 1.0)  # flat top, 12-row edges
    return 0.12 + 0.75 * band[:, None] * profile[None, :]


def encode(name: str, gray: np.ndarray, colour: bool, bits: int) -> bytes:
    full = 255 if bits == 8 else 65535
    if colour:  # a warm illumination tint; BGR order for OpenCV
        pixels = np.stack([gray * 0.80, gray * 0.95, gray], axis=-1)
    else:
        pixels = gray
    pixels = np.round(pixels * full).astype(np.uint8 if bits == 8 else np.uint16)
    params = {
        ".jpg": [cv2.IMWRITE_JPEG_QUALITY, 92],
        ".png": [cv2.IMWRITE_PNG_COMPRESSION, 9, cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_UP],
        ".tif": [cv2.IMWRITE_TIFF_COMPRESSION, cv2.IMWRITE_TIFF_COMPRESSION_ADOBE_DEFLATE],
    }.get(Path(name).suffix, [])
    ok, data = cv2.imencode(Path(name).suffix, pixels, params)
    if not ok:
        raise RuntimeError(f"OpenCV could not encode {name}")
    return data.tobytes()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=SAMPLES, help="folder to write into")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    total = 0
    for name, width, height, wavelength_mm, colour, bits in SPECS:
        data = encode(name, render(width, height, wavelength_mm), colour, bits)
        (args.out / name).write_bytes(data)
        total += len(data)
        print(f"{name}: {width}x{height}, {len(data) / 1024:.0f} KiB")
    (args.out / "README.txt").write_text(README)
    print(f"total {total / 1024:.0f} KiB in {args.out}")


if __name__ == "__main__":
    main()
