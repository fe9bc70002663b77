"""Shared test configuration: a deterministic hypothesis profile, the longest files first, a CLI runner and the
simulated studies several modules read."""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile(
    "roughsense",
    max_examples=40,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "roughsense"))

#: The tests folder; LONGEST_FILES are paths from the folder above it (the repository's root).
TESTS = Path(__file__).parent

#: The test files that take longest, longest first (BENCHMARKS.md, the suite). Under ``make test`` (pytest-xdist,
#: ``--dist loadfile --no-loadscope-reorder``) a file runs whole on one worker in collection order, so a long file
#: collected last kept one worker busy alone at the end; started first, the short files fill in around them.
LONGEST_FILES = ("tests/report/test_report.py", "tests/explore/test_explore.py", "tests/explore/test_runner.py",
                 "tests/test_tutorial.py", "tests/model/peak_law/test_domain.py", "tests/analysis/test_claims.py",
                 "tests/analysis/test_study_analysis.py", "tests/explore/test_sweep_bounds.py",
                 "tests/cli/test_interrupted.py", "tests/cli/test_study.py", "tests/cli/test_input_contract.py",
                 "tests/cli/test_fit.py", "tests/test_api_docs.py", "tests/cli/test_damaged_studies.py",
                 "tests/report/test_provenance.py", "tests/_util/test_workers.py", "tests/_util/test_lock.py",
                 "tests/model/test_jackknife_file.py", "tests/sensor/test_band.py", "tests/model/test_registry.py",
                 "tests/cli/test_studies.py", "tests/sim/test_frames.py", "tests/analysis/test_controls.py",
                 "tests/model/pls/test_simpls.py")


def pytest_collection_modifyitems(items) -> None:
    """The longest files first; every file's own tests keep their order."""
    rank = {name: i for i, name in enumerate(LONGEST_FILES)}

    def key(item) -> int:
        return rank.get(item.path.relative_to(TESTS.parent).as_posix(), len(rank))

    items.sort(key=key)  # stable: the rest keep collection order


@pytest.fixture
def run_cli(capsys):
    """Run ``roughsense ARGS`` in-process; returns (exit_code, stdout, stderr)."""
    from roughsense.cli import main

    def _run(*args: str):
        code = main([str(a) for a in args])
        captured = capsys.readouterr()
        return code, captured.out, captured.err

    return _run


@pytest.fixture
def quick_figures(monkeypatch):
    """Skip rasterising the report's figures where a test checks the page's text or tables: drawing and PNG writing
    are test_report.py's to check (its figure tests keep them), and they are a report's largest cost."""
    from roughsense.report import figures

    monkeypatch.setattr(figures, "figure_bytes", lambda figure, figure_format="png", **options: b"\x89PNG")
    monkeypatch.setattr(figures, "page_preview", lambda png, **options: png)


@pytest.fixture(scope="session")
def shared_build(tmp_path_factory):
    """``shared_build(name, build)``: the folder ``build(path)`` made, built once per test run and read-only after.

    Under pytest-xdist each worker has its own session, so the folders live beside the workers' own temporary
    folders (in the run's, not a previous run's) and a file lock lets the first worker build while the others wait.
    """
    from filelock import FileLock

    base = tmp_path_factory.getbasetemp()
    root = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "shared-studies"
    root.mkdir(exist_ok=True)

    def get(name: str, build):
        folder = root / name
        with FileLock(str(root / f"{name}.lock")):
            if not (root / f"{name}.built").is_file():
                build(folder)
                (root / f"{name}.built").touch()
        return folder

    return get


@pytest.fixture(scope="session")
def simulated_tiny(shared_build):
    """A small simulated study at the paper's scale (34.9 px/mm, 1920 x 170 frames; smooth pad, R2, R3, C4, two
    repetitions, seed 7), shared by every module that reads one: copy it before changing anything in it."""
    from roughsense.sim.config import SimulationConfig, with_image_size
    from roughsense.sim.simulate import simulate_study

    config = SimulationConfig(pads=("smooth",), specimens=("R2", "R3", "C4"), repetitions=2, seed=7, participants=3,
                              sessions=2)
    return shared_build("tiny-seed7", lambda folder: simulate_study(folder, with_image_size(config, 1920, 170), jobs=1))


@pytest.fixture()
def shared():
    """A folder every user may write, as /tmp is (pytest's tmp_path is root's alone)."""
    folder = Path(tempfile.mkdtemp(prefix="roughsense-shared-", dir="/tmp"))
    os.chmod(folder, 0o1777)
    yield folder
    shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture()
def signals():
    """The CLI's handlers (as ``run()`` installs them), Python's restored after the test."""
    import signal

    from roughsense._util import interrupt

    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a terminal, even if pytest runs in the
    interrupt.install()  # background (SIGINT inherited ignored, and kept so by install(): tests/foreground.py)
    yield interrupt
    for number, handler in saved.items():
        signal.signal(number, handler)
    interrupt._received.clear()


@pytest.fixture(scope="session")
def tiny_smooth(tmp_path_factory):
    """A tiny study folder (``make_study``: smooth pad, 2 repetitions), built once per run and read-only after."""
    from tests.analysis.test_dataset import make_study

    return make_study(tmp_path_factory.mktemp("tiny") / "study", pads=("smooth",), repetitions=2)


@pytest.fixture()
def tiny_copy(tiny_smooth, tmp_path):
    """A copy of ``tiny_smooth`` the test may damage."""
    return shutil.copytree(tiny_smooth, tmp_path / "study")


@pytest.fixture(scope="session")
def tiny_model_2n(tiny_smooth, tmp_path_factory):
    """The model ``fit`` makes of ``tiny_smooth`` at 2 N (the PLS family)."""
    from roughsense.cli import main

    path = tmp_path_factory.mktemp("model") / "m.json"
    assert main(["fit", "--study", str(tiny_smooth), "--pad", "smooth", "--condition", "2N", "--out", str(path)]) == 0
    return path
