"""Shared test configuration: a deterministic hypothesis profile, the longest files first, a CLI runner and the
simulated studies several modules read."""
from __future__ import annotations

import os

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

#: The test files that take longest, longest first (BENCHMARKS.md, the suite). Under ``make test`` (pytest-xdist,
#: ``--dist loadfile --no-loadscope-reorder``) a file runs whole on one worker in collection order, so a long file
#: collected last kept one worker busy alone at the end; started first, the short files fill in around them.
LONGEST_FILES = ("test_report.py", "test_explore.py", "test_hostile.py", "test_tutorial.py",
                 "test_trustworthy_prediction.py", "test_claims.py", "test_study_analysis.py", "test_sweep_bounds.py",
                 "test_interrupted.py", "test_cli_study.py", "test_input_contract.py", "test_cli_model.py",
                 "test_api_docs.py", "test_fuzz.py", "test_report_provenance.py", "test_workers.py", "test_locks.py",
                 "test_jackknife_file.py", "test_scale_band.py", "test_families.py", "test_cli_builtin.py",
                 "test_sim_pixels.py", "test_controls.py", "test_pls.py", "test_noise.py")


def pytest_collection_modifyitems(items) -> None:
    """The longest files first; every file's own tests keep their order."""
    rank = {name: i for i, name in enumerate(LONGEST_FILES)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: the rest keep collection order


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
