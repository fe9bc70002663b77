"""Write src/roughsense/data/examples/my-study/: a tiny study folder laid out as a user lays out their own (run once;
committed; shipped in the package, and `roughsense example my-study` copies it out).

The images come from roughsense's digital twin -- they are NOT real sensor data -- downscaled 4x with area
averaging, cut to a 40-row strip around the contact band and saved as JPEG, as if taken by a camera of
8.725 px/mm. That keeps each file near 5 KB while the spectrum (0.1-1.0 mm^-1 over a 55 mm line) is unchanged.
The tables are written in the plain form a person would type: no simulator columns, a hand-written study.toml.
docs/tutorial.md uses it. Deterministic: the same seed writes the same bytes.
"""
from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pandas as pd

from roughsense.sim.config import SimulationConfig, with_image_size
from roughsense.sim.simulate import simulate_study

EXAMPLE = Path(__file__).resolve().parents[1] / "src" / "roughsense" / "data" / "examples" / "my-study"
SPECIMENS = ("R2", "R3", "R4", "R5", "C3")
DOWNSCALE = 4
STRIP_ROWS = 40
JPEG_QUALITY = 90
PX_PER_MM = 34.9 / DOWNSCALE

STUDY_TOML = f"""# An example study folder (see README.md here and docs/tutorial.md).
# Images: roughsense's digital twin, downscaled {DOWNSCALE}x -- synthetic, NOT real sensor data.

[study]
name = "my-study"
reference_specimen = "R3"      # rated 1 by definition, never rated by the participants
synthetic = "roughsense's digital twin, downscaled {DOWNSCALE}x: an example, not real sensor data"

[sensor]
px_per_mm = {PX_PER_MM}          # this camera's scale along the line
roi = [0, 4, 480, 32]          # x, y, width, height in px: the contact band of these 480 x 40 images

[protocol]
forces_n = [1.0, 2.0, 3.0]
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=EXAMPLE, help="folder to write (replaced)")
    parser.add_argument("--seed", type=int, default=2025)
    args = parser.parse_args()
    config = SimulationConfig(pads=("fingerprint",), specimens=SPECIMENS, repetitions=2, seed=args.seed,
                              participants=5, sessions=2)
    with tempfile.TemporaryDirectory() as tmp:
        sim = simulate_study(Path(tmp) / "sim", with_image_size(config, 1920, 400), jobs=1)
        manifest = pd.read_csv(sim / "manifest.csv")
        readme = (args.out / "README.md").read_bytes() if (args.out / "README.md").is_file() else None
        if args.out.exists():
            shutil.rmtree(args.out)
        (args.out / "images").mkdir(parents=True)
        names = []
        for row in manifest.itertuples(index=False):
            frame = cv2.imread(str(sim / row.image), cv2.IMREAD_GRAYSCALE)
            small = cv2.resize(frame, (frame.shape[1] // DOWNSCALE, frame.shape[0] // DOWNSCALE),
                               interpolation=cv2.INTER_AREA)
            top = (small.shape[0] - STRIP_ROWS) // 2
            name = f"images/{row.specimen}_{row.nominal_force_n:g}N_{row.repetition}.jpg"
            ok, data = cv2.imencode(".jpg", np.ascontiguousarray(small[top:top + STRIP_ROWS]),
                                    [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            assert ok
            (args.out / name).write_bytes(data.tobytes())
            names.append(name)
        table = pd.DataFrame({"image": names, "specimen": manifest["specimen"], "pad": manifest["pad"],
                              "force_n": manifest["force_n"].round(3), "repetition": manifest["repetition"]})
        table.to_csv(args.out / "manifest.csv", index=False)
        specimens = pd.read_csv(sim / "specimens.csv")
        specimens[["specimen", "shape", "wavelength_mm"]].to_csv(args.out / "specimens.csv", index=False)
        ratings = pd.read_csv(sim / "ratings.csv")
        ratings["rating"] = ratings["rating"].round(2)
        ratings.to_csv(args.out / "ratings.csv", index=False)
        (args.out / "study.toml").write_text(STUDY_TOML)
        if readme is not None:  # the folder's README (copied out with it by `roughsense example`) is kept as it is
            (args.out / "README.md").write_bytes(readme)
    sizes = [p.stat().st_size for p in (args.out / "images").iterdir()]
    print(f"wrote {len(sizes)} images ({np.mean(sizes) / 1024:.1f} KiB each on average) to {args.out}")


if __name__ == "__main__":
    main()
