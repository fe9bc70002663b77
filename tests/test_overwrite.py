"""sim/overwrite.py: what `simulate --out S --force` reads of the folder it replaces is read safely (a FIFO never hangs it)."""
from __future__ import annotations

import os
import subprocess
import sys

from tests.commands import HANG_GUARD_S


def test_simulate_force_over_a_folder_whose_manifest_is_a_fifo_does_not_hang(tmp_path):
    """36.6's rule for the readers that inspect an output folder before replacing it (sim/overwrite.py,
    io/writer.py): `simulate --out S --force` opened S/manifest.csv by name, so a FIFO there hung the run before any
    safe point, and one SIGTERM did not end it."""
    roughsense = os.path.join(os.path.dirname(sys.executable), "roughsense")
    args = [roughsense, "simulate", "--out", str(tmp_path / "s"), "--pads", "smooth", "--specimens", "R2,R3",
            "--forces-n", "1", "--repetitions", "2", "--jobs", "1"]
    env = {**os.environ, "ROUGHSENSE_CACHE_DIR": str(tmp_path / "cache")}
    assert subprocess.run(args, capture_output=True, env=env, timeout=HANG_GUARD_S).returncode == 0
    manifest = tmp_path / "s" / "manifest.csv"
    manifest.unlink()
    os.mkfifo(manifest)
    done = subprocess.run([*args, "--force"], capture_output=True, text=True, env=env, timeout=HANG_GUARD_S)
    assert done.returncode == 0 and "Traceback" not in done.stderr
    assert manifest.is_file() and manifest.read_text().startswith("image,specimen,pad,force_n")
