"""What the tests of roughsense's commands share: the installed script, a model file of the old format, a grating
image, a dead process id, and the one error line a refusal prints."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROUGHSENSE = str(Path(sys.executable).with_name("roughsense"))
LEGACY_MODEL = Path(__file__).parent / "data" / "legacy_models" / "model_2N.json"
HUGE = 5_000_000  # a 5 MB cell stands in for the 100 MB one of the report: the same path, a fast test
HANG_GUARD_S = 300  # not a timing check: on e1630a3 these runs never end, and the suite must


def dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def grating_png(path: Path, wavelength_mm: float = 3.0) -> Path:
    import cv2
    import numpy as np

    x_mm = np.arange(1920) / 34.9
    line = 0.5 + 0.35 * np.tanh(3 * np.sin(2 * np.pi * x_mm / wavelength_mm))
    assert cv2.imwrite(str(path), np.tile(np.round(255 * line).astype(np.uint8), (1080, 1)))
    return path


def error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.startswith("roughsense: error: ")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def one_error(run_cli, *args) -> str:
    code, _, err = run_cli(*args)
    assert code == 2 and "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.startswith("roughsense: error: ")]
    assert len(lines) == 1, err
    return lines[0]


def check_output(run_cli, root) -> str:
    """What `roughsense check` prints of a folder it refuses (one line per problem)."""
    code, out, err = run_cli("check", root)
    assert code == 2 and "Traceback" not in err, err
    return out + err


def manifest_lines(root) -> list[str]:
    return (root / "manifest.csv").read_text().splitlines()


def write_lines(path, lines) -> None:
    path.write_text("\n".join(lines) + "\n")


def refusal_line(code: int, err: str) -> str:
    """The one ``roughsense: error:`` line of a refused run, every stderr line being roughsense's own."""
    assert code == 2, err[:2000]
    assert "Traceback" not in err and all(line.startswith("roughsense: ") for line in err.splitlines()), err[:2000]
    lines = [line for line in err.splitlines() if line.startswith("roughsense: error: ")]
    assert len(lines) == 1, err[:2000]
    return lines[0]
