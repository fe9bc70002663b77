"""The small sweep file the explore, lock and SLURM tests run: five specimens, small frames, the smooth pad."""
from __future__ import annotations


def small_sweep(seeds=(0,), *, max_components: int = 3) -> str:
    """A sweep.toml of ``seeds`` that a 2-core machine runs in seconds per cell."""
    return f"""
[sweep]
seeds = {list(seeds)}
repetitions = 2
specimens = ["R2", "R3", "R4", "C3", "rect:1.5"]
image_size_px = [480, 160]
max_components = {max_components}
[axes]
pad = ["smooth"]
"""


def big_sweep(tmp_path, seeds: int):
    """``small_sweep`` of ``seeds`` seeds (so as many cells), written to ``tmp_path/sweep.toml``."""
    path = tmp_path / "sweep.toml"
    path.write_text(small_sweep(range(seeds), max_components=4))
    return path


#: A sweep file with a seed and a specimen spec to fill in (``SWEEP.format(seed=0, spec='"R4"')``).
SWEEP = """
[sweep]
seeds = [{seed}]
repetitions = 2
specimens = ["R2", "R3", {spec}]
image_size_px = [480, 160]
max_components = 4
[axes]
pad = ["smooth"]
"""
