"""The simulator's pixels are pinned: a speed-up of sim/ must leave every image's decoded pixels as they were.

The features, and so every number of a study, are computed from these pixels; PNG bytes may change (an encoder
setting), the pixels may not.
"""
from __future__ import annotations

import hashlib

import cv2
import numpy as np
import pytest

from roughsense.sim import SimulationConfig, simulate_study
from roughsense.sim.frames import mount_lines, render_mount, render_trial, trial_line
from roughsense.sim.plan import mount_groups, plan_trials

#: sha256 over (name, decoded pixels) of every image of PIN_CONFIG at seed 7, by main 18bc82e (before issue 37's
#: third pass), jobs 1 and 2 alike. NumPy's and SciPy's kernels on this project's machine kind (x86-64) made them.
PIN_CONFIG = SimulationConfig(pads=("smooth", "fingerprint"), specimens=("R2", "C3.5"), forces_n=(1.0, 2.0, 3.0),
                              repetitions=2)
PINNED_PIXELS = "5030a892f32a38a024250ada5abfe97ffc3d2c5607c511d5e267476462a711f0"


def _pixel_hash(root) -> str:
    digest = hashlib.sha256()
    for path in sorted((root / "images").iterdir()):
        digest.update(path.name.encode())
        digest.update(cv2.imread(str(path), cv2.IMREAD_UNCHANGED).tobytes())
    return digest.hexdigest()


@pytest.mark.parametrize("jobs", [1, 2])
def test_simulated_pixels_are_those_pinned_before_the_speed_ups(tmp_path, jobs):
    root = simulate_study(tmp_path / "study", PIN_CONFIG, seed=7, jobs=jobs)
    assert _pixel_hash(root) == PINNED_PIXELS


def test_a_mount_rendered_together_equals_its_trials_rendered_one_by_one():
    """render_mount solves a mount's forces as one batch; every row must take the steps it takes alone."""
    trials = plan_trials(PIN_CONFIG, *PIN_CONFIG.validate())
    groups = mount_groups(trials)
    assert [t for group in groups for t in group] == trials
    assert {len(group) for group in groups} == {3}  # one mount, its three forces
    for group in (groups[0], groups[-1]):  # the smooth pad, and the fingerprint pad with its ridges
        for trial, (line, fraction), (frame, same) in zip(group, mount_lines(group), render_mount(group)):
            alone_line, alone_fraction = trial_line(trial)
            alone_frame, _ = render_trial(trial)
            assert np.array_equal(line, alone_line) and fraction == alone_fraction == same
            assert np.array_equal(frame, alone_frame)


def test_mount_lines_refuses_trials_of_different_mounts():
    trials = plan_trials(PIN_CONFIG, *PIN_CONFIG.validate())
    with pytest.raises(ValueError, match="one mount"):
        mount_lines([trials[0], trials[3]])
