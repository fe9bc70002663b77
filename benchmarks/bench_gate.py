"""Benchmark the contact-image gate (issue 43): hostile images withheld or flagged, in-distribution presses of other
sessions of the twin let through, per pad's default model fitted on the built-in study.

Builds the hostile set in a temporary folder, at the rig's frame size (that of the built-in study's images):

* real photographs bundled with scikit-image (no download): resized to the frame, and a frame-sized crop of each;
* noise of three colours (white, pink, brown), several draws; a blank frame of 100 +- 2 DN; a bare-background frame
  (a press's rows outside the band, tiled); a typed page of text;
* the other pad's presses; the model's own pad's presses rotated 10-30 degrees, and magnified 10-25 % (linear and
  cubic interpolation).

Then reads, alone, every press at the model's force of other sessions of the twin (``simulate --seed K``; the gate
was designed on seed 0 only, the built-in study) and reports the share withheld or flagged, and the gate's
false-alarm rate (withheld only) against alpha with its binomial standard error.

Run: .venv/bin/python benchmarks/bench_gate.py [--seeds 11 12] [--out DIR]
"""
from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import cv2
import numpy as np

import roughsense as rs

PHOTOS = ("camera", "moon", "text", "brick", "grass", "gravel", "page", "coins", "coffee", "chelsea", "astronaut",
          "rocket", "clock", "cell", "horse")
CONDITION = "2N"


def roughsense(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "roughsense.cli", *args], check=True, capture_output=True)


def fitted(pad: str, folder: Path) -> Path:
    out = folder / f"{pad}.json"
    if not out.exists():
        roughsense("fit", "--study", "builtin", "--pad", pad, "--condition", CONDITION, "--out", str(out))
    return out


def builtin_images(pad: str) -> list[Path]:
    study = rs.read_study(_builtin())
    rows = study.manifest[(study.manifest["pad"] == pad) & (study.manifest["condition"] == CONDITION)]
    return [study.root / image for image in rows["image"]]


def _builtin() -> Path:
    from roughsense.cli._studies import resolve_study

    return Path(resolve_study("builtin", seed=0, jobs=1))


def coloured_noise(rng, shape, exponent: float) -> np.ndarray:
    """Noise whose power falls as 1/f^exponent (0 white, 1 pink, 2 brown), scaled to 100 +- 30 DN."""
    spectrum = np.fft.rfft2(rng.normal(size=shape))
    fy, fx = np.meshgrid(np.fft.fftfreq(shape[0]), np.fft.rfftfreq(shape[1]), indexing="ij")
    f = np.hypot(fy, fx)
    f[0, 0] = 1.0
    field = np.fft.irfft2(spectrum / f ** (exponent / 2), s=shape)
    return np.clip(100 + 30 * (field - field.mean()) / field.std(), 0, 255).astype(np.uint8)


def _gray(image) -> np.ndarray:
    image = np.asarray(image)
    if image.dtype == bool:
        image = image.astype(np.uint8) * 255
    if image.ndim == 3:
        image = cv2.cvtColor(image[..., :3], cv2.COLOR_RGB2GRAY)
    return image.astype(np.uint8)


def hostile_set(shape, own: list[Path], other: list[Path], rng) -> dict[str, list[np.ndarray]]:
    """Class name -> frames (uint8 gray, the rig's frame size)."""
    import skimage.data as data

    h, w = shape
    photos = []
    for name in PHOTOS:
        image = _gray(getattr(data, name)())
        photos.append(cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA))
        scale = max(w / image.shape[1], h / image.shape[0])
        big = cv2.resize(image, (math.ceil(image.shape[1] * scale), math.ceil(image.shape[0] * scale)))
        photos.append(big[:h, :w])
    page = np.full(shape, 235, np.uint8)
    for line in range(8):
        cv2.putText(page, "The quick brown fox jumps over the lazy dog 0123456789 " * 2, (10, 35 + 38 * line),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.9, 20, 2)
    press = cv2.imread(str(own[0]), cv2.IMREAD_GRAYSCALE)
    background = np.tile(press[:20], (h // 20 + 1, 1))[:h]
    classes = {
        "photographs": photos,
        "white noise": [coloured_noise(rng, shape, 0) for _ in range(4)],
        "pink noise": [coloured_noise(rng, shape, 1) for _ in range(4)],
        "brown noise": [coloured_noise(rng, shape, 2) for _ in range(4)],
        "blank frame": [np.clip(100 + rng.normal(0, 2, shape), 0, 255).astype(np.uint8) for _ in range(3)],
        "bare background": [background],
        "typed page": [page],
        "other pad": [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in other[::10]],
    }
    picks = [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in own[::20]]
    classes["rotated 10-30 deg"] = [_warp(p, angle, 1.0, cv2.INTER_LINEAR) for p in picks for angle in (10, 15, 20, 30)]
    classes["magnified 10-25 %"] = [_warp(p, 0, scale, flags) for p in picks for scale in (1.10, 1.15, 1.20, 1.25)
                                    for flags in (cv2.INTER_LINEAR, cv2.INTER_CUBIC)]
    return classes


def _warp(image: np.ndarray, angle: float, scale: float, flags: int) -> np.ndarray:
    h, w = image.shape
    matrix = cv2.getRotationMatrix2D((w / 2, h / 2), angle, scale)
    return cv2.warpAffine(image, matrix, (w, h), flags=flags, borderMode=cv2.BORDER_REFLECT)


def caught(model: Path, frames: list[np.ndarray]):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = rs.predict(str(model), frames)
    return int(table["withheld"].sum()), int((table["withheld"] | table["extrapolates"]).sum()), table


def rotation_goal(model: Path, own: list[Path]) -> None:
    """Issue 43: a press turned 0-20 degrees moves at most 3 % or is withheld or flagged."""
    picks = [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in own[::10]]
    angles = (0.5, 1, 2, 3, 5, 8, 12, 16, 20)
    frames = list(picks) + [_warp(p, a, 1.0, cv2.INTER_LINEAR) for a in angles for p in picks]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = rs.predict(str(model), frames)
    column = next(c for c in table.columns if c.startswith("roughness_rel_"))
    base = np.tile(table[column].to_numpy()[:len(picks)], len(angles))
    turned = table.iloc[len(picks):]
    moved = np.abs(turned[column].to_numpy() / base - 1)
    caught = (turned["withheld"] | turned["extrapolates"]).to_numpy()
    bad = int((~caught & ~(moved <= 0.03)).sum())
    print(f"  rotated 0.5-20 deg: {len(turned)} presses, {int(caught.sum())} withheld or flagged, of the rest the "
          f"largest move {np.nanmax(np.where(caught, np.nan, moved)) if (~caught).any() else 0:.1%}; moved > 3 % "
          f"and not caught: {bad}")


def in_distribution(model: Path, pad: str, seeds, folder: Path) -> None:
    for seed in seeds:
        study = folder / f"seed{seed}"
        if not study.exists():
            roughsense("simulate", "--seed", str(seed), "--out", str(study))
        rows = rs.read_study(study).manifest
        rows = rows[(rows["pad"] == pad) & (rows["condition"] == CONDITION)]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            table = rs.predict(str(model), [str(study / image) for image in rows["image"]])
        n, withheld = len(table), int(table["withheld"].sum())
        flagged = int((table["withheld"] | table["extrapolates"]).sum())
        se = math.sqrt(0.01 * 0.99 / n)
        print(f"  {pad:11s} seed {seed}: {n} presses read alone: withheld {withheld} ({withheld / n:.1%}; alpha 1 % "
              f"+- {se:.1%} binomial SE), withheld or flagged {flagged} ({flagged / n:.1%}), flagged 'rotated' "
              f"{int(table['outside'].str.contains('rotated').sum())}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="*", default=[11, 12])
    parser.add_argument("--out", type=Path, default=None, help="keep models and studies here (default: a temp dir)")
    args = parser.parse_args()
    folder = args.out or Path(tempfile.mkdtemp(prefix="bench-gate-"))
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(43)
    for pad, other_pad in (("smooth", "fingerprint"), ("fingerprint", "smooth")):
        model = fitted(pad, folder)
        own, other = builtin_images(pad), builtin_images(other_pad)
        shape = cv2.imread(str(own[0]), cv2.IMREAD_GRAYSCALE).shape
        print(f"{pad} pad model ({CONDITION}, built-in study), frames {shape[1]} x {shape[0]} px:")
        total = total_caught = 0
        for name, frames in hostile_set(shape, own, other, rng).items():
            withheld, either, table = caught(model, frames)
            total, total_caught = total + len(frames), total_caught + either
            missed = [int(i) for i in np.flatnonzero(~(table["withheld"] | table["extrapolates"]).to_numpy())]
            print(f"  {name:18s} {either:3d}/{len(frames):<3d} withheld or flagged ({withheld} withheld)"
                  + (f"  missed: frames {missed}" if missed else ""))
        print(f"  hostile total: {total_caught}/{total} ({total_caught / total:.0%})")
        rotation_goal(model, own)
        in_distribution(model, pad, args.seeds, folder)


if __name__ == "__main__":
    main()
