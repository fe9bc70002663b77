"""The package as a user receives it: ``make dist`` makes a wheel and an sdist (saying so in a line, not hundreds),
both install into a clean venv with the report template, the paper's tables, the sample images and the examples, and
``roughsense --version`` and ``roughsense example`` work there, away from any checkout.

Marked ``package`` (and slow): it installs every dependency into a fresh venv (from the registry or its mirror,
through pip's own cache), so ``make test`` leaves it out and CI runs it as its own step (``.ci/run``).
Run it with ``python -m pytest -m package``.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tarfile
import venv
import zipfile
from pathlib import Path

import pytest

import roughsense

pytestmark = [pytest.mark.slow, pytest.mark.package]

ROOT = Path(__file__).resolve().parents[1]
VERSION = roughsense.__version__
DATA = [
    "roughsense/report/templates/report.html.j2",
    "roughsense/data/paper/paper_results.csv",
    "roughsense/data/paper/perceived_roughness.csv",
    "roughsense/data/samples/README.txt",
    "roughsense/data/samples/synthetic_grating_3mm_gray8_1920x1080.png",
    "roughsense/data/examples/my-study/study.toml",
    "roughsense/data/examples/my-study/manifest.csv",
    "roughsense/data/examples/tiny.toml",
    "roughsense/data/examples/paper_questions.toml",
]
SAMPLES = 5
EXAMPLE_IMAGES = 30  # my-study/images
_ANYWHERE = shutil.ignore_patterns(".git", "*.egg-info", "__pycache__", ".pytest_cache", ".hypothesis")
_AT_TOP = {".venv", "build", "dist", "report", ".cache"}  # a checkout's outputs (src/roughsense/report is code)


def _junk(folder: str, names: list[str]) -> set[str]:
    top = {n for n in names if n in _AT_TOP} if Path(folder) == ROOT else set()
    return top | _ANYWHERE(folder, names)


def _run(args, **kwargs) -> subprocess.CompletedProcess:
    result = subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=900, **kwargs)
    assert result.returncode == 0, f"{' '.join(map(str, args))} failed:\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    return result


@pytest.fixture(scope="module")
def dist(tmp_path_factory) -> dict[str, Path]:
    """``make dist`` in a clean copy, so a stale build/ folder in the checkout can never leak into the wheel.

    The copy has no .venv: make is pointed at this interpreter's, with a fresh stamp so it installs nothing.
    """
    tmp = tmp_path_factory.mktemp("package")
    source = shutil.copytree(ROOT, tmp / "source", ignore=_junk)
    (tmp / "stamp").touch()
    made = _run(["make", "dist", f"BIN={Path(sys.executable).parent}", f"STAMP={tmp / 'stamp'}"], cwd=source)
    lines = (made.stdout + made.stderr).strip().splitlines()
    assert len(lines) <= 3 and "roughsense" in lines[-1], lines[:20]  # not the build's 545-line log
    wheels, sdists = list((source / "dist").glob("*.whl")), list((source / "dist").glob("*.tar.gz"))
    assert len(wheels) == 1 and len(sdists) == 1
    return {"wheel": wheels[0], "sdist": sdists[0], "tmp": tmp}


@pytest.fixture(scope="module")
def clean_venv(dist) -> Path:
    """A venv with nothing but pip, and the wheel (with its dependencies) installed into it."""
    env_dir = dist["tmp"] / "venv"
    venv.EnvBuilder(with_pip=True, clear=True).create(env_dir)
    _run([env_dir / "bin" / "python", "-m", "pip", "install", "--quiet", dist["wheel"]])
    return env_dir


def test_the_wheel_and_sdist_are_named_for_the_version(dist):
    assert dist["wheel"].name == f"roughsense-{VERSION}-py3-none-any.whl"
    assert dist["sdist"].name == f"roughsense-{VERSION}.tar.gz"


def test_the_wheel_holds_the_data_and_the_entry_point(dist):
    names = set(zipfile.ZipFile(dist["wheel"]).namelist())
    assert set(DATA) <= names
    assert sum(n.startswith("roughsense/data/samples/synthetic_grating_") for n in names) == SAMPLES
    assert sum(n.startswith("roughsense/data/examples/my-study/images/") for n in names) == EXAMPLE_IMAGES
    entry_points = zipfile.ZipFile(dist["wheel"]).read(f"roughsense-{VERSION}.dist-info/entry_points.txt").decode()
    assert "roughsense = roughsense.cli:run" in entry_points
    assert not any("/tests/" in n or n.startswith(("tests/", "build/")) for n in names)


def _requires(wheel: Path) -> list[str]:
    metadata = zipfile.ZipFile(wheel).read(f"roughsense-{VERSION}.dist-info/METADATA").decode()
    return [line.removeprefix("Requires-Dist:").strip() for line in metadata.splitlines()
            if line.startswith("Requires-Dist:")]


def test_the_wheel_requires_no_contact_mechanics_chain_at_run_time(dist):
    """ContactMechanics (GPL-3, with muFFT and NuMPI) only checks the twin in a test: a user's install never pulls it."""
    requires = _requires(dist["wheel"])
    assert any(r.startswith("numpy") for r in requires)
    chain = ("contactmechanics", "mufft", "numpi", "surfacetopography")
    runtime = [r for r in requires if "extra ==" not in r]
    assert not [r for r in runtime if r.lower().startswith(chain)], runtime
    assert all('extra == "test"' in r for r in requires if r.lower().startswith(chain))
    assert any(r.lower().startswith("contactmechanics") for r in requires)  # still in the test extra


def test_the_sdist_holds_the_sources_docs_tests_and_example(dist):
    prefix = f"roughsense-{VERSION}/"
    with tarfile.open(dist["sdist"]) as sdist:
        names = {n.removeprefix(prefix) for n in sdist.getnames()}
    expected = {"pyproject.toml", "README.md", "LICENSE", "Makefile", "docs/tutorial.md", "tests/test_tutorial.py",
                "scripts/make_example_study.py", *(f"src/{d}" for d in DATA)}
    assert expected <= names, sorted(expected - names)
    assert not any("__pycache__" in n for n in names)


def _check_installed(env_dir: Path, work: Path) -> None:
    """Run the installed command, away from the checkout, so nothing can be imported from the source tree."""
    bin_dir = env_dir / "bin"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "ROUGHSENSE_DEBUG")}
    env["ROUGHSENSE_CACHE_DIR"] = str(work / "cache")
    work.mkdir(parents=True, exist_ok=True)
    version = _run([bin_dir / "roughsense", "--version"], cwd=work, env=env)
    assert version.stdout.strip() == f"roughsense {VERSION}"
    where = _run([bin_dir / "python", "-c", "import roughsense, pathlib; print(pathlib.Path(roughsense.__file__).parent)"],
                 cwd=work, env=env).stdout.strip()
    package = Path(where)
    assert env_dir in package.parents, f"imported from {package}, not from the venv"
    for name in DATA:
        assert (package.parent / name).is_file(), name
    samples = sorted((package / "data" / "samples").glob("synthetic_grating_*"))
    assert len(samples) == SAMPLES
    _run([bin_dir / "roughsense", "features", "--roi", "auto", "--out", "features.csv", *samples], cwd=work, env=env)
    assert len((work / "features.csv").read_text().splitlines()) == SAMPLES + 1


def _example_from_the_installed_package(bin_dir: Path, tmp_path: Path, env: dict) -> Path:
    """The tutorial's first step away from a clone: the shipped study folder, copied out of the installed package."""
    _run([bin_dir / "roughsense", "example", "my-study", "--out", "my-study"], cwd=tmp_path, env=env)
    study = tmp_path / "my-study"
    assert len(list((study / "images").glob("*.jpg"))) == EXAMPLE_IMAGES and (study / "study.toml").is_file()
    again = subprocess.run([bin_dir / "roughsense", "example", "my-study", "--out", "my-study"], cwd=tmp_path,
                           env=env, capture_output=True, text=True, timeout=120)
    assert again.returncode == 2 and "--force" in again.stderr and len(again.stderr.strip().splitlines()) == 1
    return study


def test_the_wheel_installs_and_runs_in_a_clean_venv(clean_venv, dist, tmp_path):
    listed = _run([clean_venv / "bin" / "python", "-m", "pip", "list", "--format=freeze"]).stdout.lower()
    assert not [n for n in ("contactmechanics", "mufft", "numpi") if f"\n{n}==" in f"\n{listed}"], listed
    _check_installed(clean_venv, tmp_path / "wheel")
    # The report renders from the installed template, with the paper's published values from the installed tables.
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "ROUGHSENSE_DEBUG")}
    env["ROUGHSENSE_CACHE_DIR"] = str(tmp_path / "cache")
    study = _example_from_the_installed_package(clean_venv / "bin", tmp_path, env)
    _run([clean_venv / "bin" / "roughsense", "study", "--study", study, "--out", tmp_path / "report",
          "--max-components", "2", "--no-loso"], cwd=tmp_path, env=env)
    html = (tmp_path / "report" / "index.html").read_text()
    assert "<html" in html.lower() and "paper" in html.lower()


def test_the_sdist_installs_too(clean_venv, dist, tmp_path):
    _run([clean_venv / "bin" / "python", "-m", "pip", "install", "--quiet", "--no-deps", "--force-reinstall",
          dist["sdist"]])
    _check_installed(clean_venv, tmp_path / "sdist")
