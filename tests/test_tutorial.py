"""docs/tutorial.md cannot rot: every fenced ``sh`` block runs, in order, in a fresh folder.

The folder holds copies of examples/ and the shipped samples at their repository paths; ``roughsense`` on PATH is
a shim for the interpreter running the tests, so the tutorial runs against this checkout's code.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

import roughsense

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "tutorial.md"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.MULTILINE | re.DOTALL)


def blocks(kind: str) -> list[str]:
    return [body for lang, body in FENCE.findall(TUTORIAL.read_text()) if lang == kind]


def test_the_tutorial_starts_from_the_readme_quick_start():
    readme_quick_start = FENCE.findall((ROOT / "README.md").read_text())[0]
    assert readme_quick_start[1].split() == ["make", "study", "make", "test"]
    assert blocks("text")[0] == readme_quick_start[1]
    assert "docs/tutorial.md" in (ROOT / "README.md").read_text()


def test_every_fenced_block_is_sh_or_text():
    """A block in another language would silently escape the run below."""
    assert {lang for lang, _ in FENCE.findall(TUTORIAL.read_text())} == {"sh", "text"}


@pytest.mark.slow
def test_every_sh_block_runs(tmp_path):
    work = tmp_path / "work"
    shutil.copytree(ROOT / "examples", work / "examples")
    samples = Path(roughsense.__file__).parent / "data" / "samples"
    shutil.copytree(samples, work / "src" / "roughsense" / "data" / "samples")
    shim = tmp_path / "bin" / "roughsense"
    shim.parent.mkdir()
    shim.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m roughsense.cli "$@"\n')
    shim.chmod(0o755)
    env = {
        **os.environ,
        "PATH": f"{shim.parent}{os.pathsep}{os.environ.get('PATH', '')}",
        "PYTHONPATH": os.pathsep.join(filter(None, [str(Path(roughsense.__file__).parents[1]),
                                                     os.environ.get("PYTHONPATH")])),
        "ROUGHSENSE_CACHE_DIR": str(tmp_path / "cache"),
        "COLUMNS": "80",
    }
    env.pop("ROUGHSENSE_DEBUG", None)
    commands = blocks("sh")
    assert len(commands) >= 10
    for body in commands:
        result = subprocess.run(["bash", "-euo", "pipefail", "-c", body], cwd=work, env=env,
                                capture_output=True, text=True, timeout=300)
        assert result.returncode == 0, f"tutorial block failed:\n{body}\n--- stderr:\n{result.stderr}"
    # What the tutorial says its commands leave behind.
    assert len(pd.read_csv(work / "sample-features.csv")) == 5
    report = work / "my-report"
    assert (report / "index.html").is_file()
    results = pd.read_csv(report / "results.csv")
    assert set(results["specimen"]) == {"R2", "R3", "R4", "R5", "C3"} and set(results["pad"]) == {"fingerprint"}
    prediction = pd.read_csv(work / "my-prediction.csv")
    assert len(prediction) == 1 and prediction["roughness"].between(0.0, 5.0).all()


def test_the_samples_readme_suggests_a_command_the_tutorial_runs():
    readme = (Path(roughsense.__file__).parent / "data" / "samples" / "README.txt").read_text()
    suggested = [line.strip() for line in readme.splitlines() if line.strip().startswith("roughsense ")]
    assert suggested, "the samples' README suggests no command"
    run = "\n".join(blocks("sh"))
    for command in suggested:
        assert command.replace("features.csv", "sample-features.csv") in run, command
