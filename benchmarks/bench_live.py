"""Live scoring throughput from a 1080p video source (issue 7 asks for >= 10 updates/s).

Peers measured in the same run, over the same synthetic 1080p clip:
  decode           cv2.VideoCapture.read alone: the floor any live loop sits on
  source           FrameSource.read_next: decode + BGR->RGB
  live_scores      decode + real scoring (roughsense.spatial_spectrum + a linear model)
  live+render      the same, drawn on a rich.Live display (to a null console)
for an MJPG .avi (what USB cameras stream at 1080p) and an MPEG-4 Part 2 .mp4.

Run: .venv/bin/python benchmarks/bench_live.py [--frames 60] [--repeats 5]
"""
from __future__ import annotations

import argparse
import io
import statistics
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from roughsense.rig.camera import open_source
from roughsense.rig.live import live_scores, render_live

PX_PER_MM = 34.9
WIDTH, HEIGHT = 1920, 1080


def make_clip(path: Path, fourcc: str, n_frames: int, rng: np.random.Generator) -> bool:
    """A contact band (3 mm grating seen through the pad) with sensor noise, drifting a little per frame."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 30, (WIDTH, HEIGHT))
    if not writer.isOpened():
        return False
    x_mm = np.arange(WIDTH) / PX_PER_MM
    for k in range(n_frames):
        frame = np.full((HEIGHT, WIDTH), 60.0)
        band = 120 + 80 * np.sin(2 * np.pi * (x_mm + 0.05 * k) / 3.0)
        frame[HEIGHT // 2 - 90 : HEIGHT // 2 + 90, :] = band
        frame += rng.normal(0, 6, frame.shape)
        gray = np.clip(frame, 0, 255).astype(np.uint8)
        writer.write(cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR))
    writer.release()
    return True


def make_scorer(rng: np.random.Generator):
    """Feature extraction + linear model, as `predict --live` will do it."""
    try:
        from roughsense.sensor.line import spatial_spectrum
    except ImportError:  # the sensor module is not there: time crop + gray + FFT by hand
        spatial_spectrum = None
    coef = rng.normal(0, 0.1, 45)
    if spatial_spectrum is not None:
        def score(frame: np.ndarray) -> float:
            return 1.0 + float(coef @ spatial_spectrum(frame, px_per_mm=PX_PER_MM, roi="center"))
        return score, "roughsense.spatial_spectrum + linear model"

    freqs = np.linspace(0.1, 1.0, 45)

    def score(frame: np.ndarray) -> float:
        y0, x0 = (frame.shape[0] - 150) // 2, (frame.shape[1] - 1900) // 2
        row = frame[y0 + 75, x0 : x0 + 1900].astype(float) @ np.array([0.2989, 0.5870, 0.1140])
        spectrum = np.abs(np.fft.rfft((row - row.mean()) * np.hanning(row.size)))
        f = np.fft.rfftfreq(row.size, d=1 / PX_PER_MM)
        return 1.0 + float(coef @ np.interp(freqs, f, spectrum))
    return score, "hand-written crop + gray + FFT + linear model"


def rates(peers: dict, n_frames: int, repeats: int) -> dict[str, float]:
    """Median frames (updates) per second per peer; rounds interleave the peers so load drift hits all alike."""
    samples: dict[str, list[float]] = {name: [] for name in peers}
    for _ in range(repeats):
        for name, run in peers.items():
            t0 = time.perf_counter()
            count = run()
            elapsed = time.perf_counter() - t0
            assert count == n_frames, (name, count, n_frames)
            samples[name].append(count / elapsed)
    return {name: statistics.median(values) for name, values in samples.items()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    rng = np.random.default_rng(7)
    score, scorer_name = make_scorer(rng)
    print(f"scoring: {scorer_name}; {args.frames} frames of {WIDTH}x{HEIGHT}, median of {args.repeats} runs")
    print(f"{'clip':<10}{'peer':<14}{'updates/s':>10}{'ms/frame':>10}{'vs decode':>11}")
    worst = float("inf")
    with tempfile.TemporaryDirectory() as tmp:
        for suffix, fourcc in ((".avi", "MJPG"), (".mp4", "mp4v")):
            clip = Path(tmp) / f"clip{suffix}"
            if not make_clip(clip, fourcc, args.frames, rng):
                print(f"{fourcc:<10}(no encoder in this OpenCV build)")
                continue

            def decode():
                capture = cv2.VideoCapture(str(clip))
                n = 0
                while capture.read()[0]:
                    n += 1
                capture.release()
                return n

            def source():
                with open_source(clip) as frames:
                    return sum(1 for _ in frames)

            def scored():
                return sum(1 for _ in live_scores(str(clip), score))

            def rendered():
                console = __import__("rich.console", fromlist=["Console"]).Console(file=io.StringIO(), width=80)
                return render_live(live_scores(str(clip), score), console=console).updates

            peers = {"decode": decode, "source": source, "live_scores": scored, "live+render": rendered}
            measured = rates(peers, args.frames, args.repeats)
            base = measured["decode"]
            for name, per_s in measured.items():
                if name in ("live_scores", "live+render"):
                    worst = min(worst, per_s)
                print(f"{fourcc:<10}{name:<14}{per_s:>10.1f}{1000 / per_s:>10.1f}{per_s / base:>11.2f}")
    verdict = "PASS" if worst >= 10 else "FAIL"
    print(f"slowest live path: {worst:.1f} updates/s -> {verdict} (target >= 10)")
    return 0 if worst >= 10 else 1


if __name__ == "__main__":
    sys.exit(main())
