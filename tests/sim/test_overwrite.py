"""sim/overwrite.py: what `simulate --out S --force` reads of the folder it replaces is read safely (a FIFO never hangs it)."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

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


def test_only_an_interrupted_simulation_or_an_empty_folder_is_replaced_without_force(tmp_path):
    """What check_overwritable lets a simulation replace: told by study.toml's [simulation] table and the marker."""
    from roughsense.errors import OutputExistsError
    from roughsense.sim.overwrite import check_overwritable, is_complete_simulation, is_simulated_study

    root = tmp_path / "s"
    (root / "images").mkdir(parents=True)
    check_overwritable(root, force=False)  # an empty images/ is an empty folder
    (root / "study.toml").write_text('[study]\nname = "mine"\n')
    assert not is_simulated_study(root)
    with pytest.raises(OutputExistsError, match="is not a simulated study"):
        check_overwritable(root, force=True)
    (root / "study.toml").write_text('[study]\nname = "sim"\n[simulation]\nseed = 0\n')
    assert is_simulated_study(root) and not is_complete_simulation(root)
    check_overwritable(root, force=False)  # interrupted: replaced without --force
    (root / ".simulation-complete").touch()
    assert is_complete_simulation(root)
    with pytest.raises(OutputExistsError, match="folder exists and is not empty"):
        check_overwritable(root, force=False)
    check_overwritable(root, force=True)
