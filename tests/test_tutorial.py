"""docs/tutorial.md cannot rot: every fenced ``sh`` block runs, in order, as one shell session would run them.

It starts in a folder standing in for the clone, with HOME a fresh folder, and each block starts where the one
before it left off (the tutorial's ``cd`` into its scratch folder carries over). ``roughsense`` on PATH is a shim for
the interpreter running the tests, so the tutorial runs against this checkout's code, and everything it reads comes
out of the package (``roughsense example``), as it would from a wheel. Each command is a process of its own, forked
from a server that has imported the libraries the CLI loads (tests/forkserver.py), so twenty commands do not pay
twenty interpreter start-ups. Every step that writes says ``--force``, so it
re-runs; the clone stand-in must stay empty; the report sections the tutorial lists and the numbers it quotes are the run's.
"""
from __future__ import annotations

import html
import os
import re
import subprocess
from pathlib import Path

import pandas as pd
import pytest

import roughsense
from tests.forkserver import fork_server

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "tutorial.md"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.MULTILINE | re.DOTALL)
SCRATCH = "roughsense-tutorial"  # the folder the tutorial names, under HOME


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


def test_the_tutorial_moves_to_its_scratch_folder_before_writing_anything():
    first = blocks("sh")[0].splitlines()[0]
    assert first == f"mkdir -p ~/{SCRATCH} && cd ~/{SCRATCH}", first


def _environment(tmp_path: Path) -> dict[str, str]:
    """The shell's environment: a fresh HOME and cache, and tmp_path/bin (where the ``roughsense`` shim goes) on PATH."""
    (tmp_path / "bin").mkdir()
    env = {
        **os.environ,
        "HOME": str(tmp_path / "home"),
        "PATH": f"{tmp_path / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}",
        "PYTHONPATH": os.pathsep.join(filter(None, [str(Path(roughsense.__file__).parents[1]),
                                                     os.environ.get("PYTHONPATH")])),
        "ROUGHSENSE_CACHE_DIR": str(tmp_path / "cache"),
        "COLUMNS": "80",
    }
    env.pop("ROUGHSENSE_DEBUG", None)
    (tmp_path / "home").mkdir()
    return env


def _run_tutorial(start: Path, env: dict[str, str], state: Path) -> Path:
    """Every sh block in order, each starting in the folder the one before it ended in; returns the last folder."""
    cwd = start
    for body in blocks("sh"):
        script = f'{body}\npwd > "{state}"\n'
        result = subprocess.run(["bash", "-euo", "pipefail", "-c", script], cwd=cwd, env=env,
                                capture_output=True, text=True, timeout=300)
        assert result.returncode == 0, f"tutorial block failed in {cwd}:\n{body}\n--- stderr:\n{result.stderr}"
        cwd = Path(state.read_text().strip())
    return cwd


@pytest.fixture(scope="module")
def tutorial_run(tmp_path_factory) -> Path:
    """The tutorial run from a stand-in clone; the scratch folder it worked in."""
    tmp = tmp_path_factory.mktemp("tutorial")
    env = _environment(tmp)
    clone = tmp / "clone"
    clone.mkdir()
    commands = blocks("sh")
    assert len(commands) >= 10
    with fork_server(env) as shim:
        (tmp / "bin" / "roughsense").write_text(shim)
        (tmp / "bin" / "roughsense").chmod(0o755)
        first = _run_tutorial(clone, env, tmp / "pwd")
    assert first == tmp / "home" / SCRATCH
    assert list(clone.iterdir()) == [], "the tutorial wrote into the folder it was started from (the clone)"
    return first


def test_every_step_that_writes_can_run_again():
    """Re-runnable, without running the whole tutorial a second time: every
    roughsense command that writes a file or folder (``--out``, or ``example``'s folder) says ``--force``."""
    commands = [line.split() for body in blocks("sh") for line in body.splitlines() if line.startswith("roughsense ")]
    writing = [c for c in commands if "--out" in c or c[1] == "example"]
    assert len(writing) >= 10
    assert [" ".join(c) for c in writing if "--force" not in c] == []


@pytest.mark.slow
def test_every_sh_block_runs_and_leaves_what_it_says(tutorial_run):
    work = tutorial_run
    assert len(pd.read_csv(work / "sample-features.csv")) == 5
    report = work / "my-report"
    assert (report / "index.html").is_file()
    page = (report / "index.html").read_text()  # the example's images are synthetic: never called user data
    assert "user data" not in page and "images are synthetic" in page
    results = pd.read_csv(report / "results.csv")
    assert set(results["specimen"]) == {"R2", "R3", "R4", "R5", "C3"} and set(results["pad"]) == {"fingerprint"}
    prediction = pd.read_csv(work / "my-prediction.csv")
    assert len(prediction) == 1 and prediction.filter(like="roughness_rel_").iloc[:, 0].between(0.0, 5.0).all()
    assert "jackknife90_low" in prediction and "pi90_low" not in prediction  # fewer than 9 specimens, as it says


def _section(title_start: str) -> str:
    text = TUTORIAL.read_text()
    start = text.index(f"## {title_start}")
    end = text.find("\n## ", start + 1)
    return text[start:end if end > 0 else None]


@pytest.mark.slow
def test_the_tutorial_lists_every_section_of_the_report_in_order(tutorial_run):
    page = (tutorial_run / "my-report" / "index.html").read_text()
    headings = [html.unescape(re.sub(r"<[^>]+>", "", h)).strip() for h in re.findall(r"<h2[^>]*>(.*?)</h2>", page, re.S)]
    assert len(headings) >= 10 and headings[0].startswith("Surfaces held out of training")
    listed = re.findall(r"^- \*\*(.+?)\*\*", _section("6. Reading the report"), re.MULTILINE)
    assert listed == [h.split(" (")[0] for h in headings], (listed, headings)


def _agrees(quoted: str, value: float) -> bool:
    """A figure quoted with d decimals agrees if the value rounds to it (half a unit of its last digit)."""
    decimals = len(quoted.split(".")[1]) if "." in quoted else 0
    return abs(value - float(quoted)) <= 0.5 * 10.0**-decimals + 1e-9


@pytest.mark.slow
def test_the_numbers_the_tutorial_comments_are_the_runs(tutorial_run, tmp_path):
    """The table of section 4 (perceived, PLS, peak law per candidate) and the misses quoted below it."""
    from roughsense.cli import main

    work = tutorial_run
    means = {}
    for model in ("model", "law"):
        out = tmp_path / f"{model}.csv"
        assert main(["predict", str(work / f"{model}.json"), "--study", str(work / "candidate"), "--out", str(out)]) == 0
        table = pd.read_csv(out)
        means[model] = table.groupby("specimen")[[c for c in table if c.startswith("roughness_rel_")][0]].mean()
    perceived = pd.read_csv(work / "candidate-perceived.csv").set_index("specimen")["gmean"]
    section = _section("4. Fit a model and predict")
    rows = re.findall(r"^\| (\w[\w.]*) \| (\d\.\d\d) \| (\d\.\d\d) \| (\d\.\d\d) \|$", section, re.MULTILINE)
    assert {r[0] for r in rows} == {"rect_2.5", "sin_3_0.5"}, rows
    for specimen, seen, pls, law in rows:
        assert _agrees(seen, perceived[specimen]), (specimen, seen, perceived[specimen])
        assert _agrees(pls, means["model"][specimen]) and _agrees(law, means["law"][specimen]), (specimen, means)
    miss = {(m, s): abs(means[m][s] - perceived[s]) for m in means for s in perceived.index if s in means[m]}
    pls_miss, law_miss = re.search(r"PLS misses it by (\d\.\d\d).*?by (\d\.\d\d)", section, re.S).groups()
    assert _agrees(pls_miss, miss[("model", "rect_2.5")]) and _agrees(law_miss, miss[("law", "rect_2.5")])
    both = re.search(r"The sinusoid both miss \((\d\.\d\d), (\d\.\d\d)\)", section).groups()
    assert _agrees(both[0], miss[("model", "sin_3_0.5")]) and _agrees(both[1], miss[("law", "sin_3_0.5")])


def test_the_samples_readme_suggests_a_command_the_tutorial_runs():
    readme = (Path(roughsense.__file__).parent / "data" / "samples" / "README.txt").read_text()
    suggested = [line.strip() for line in readme.splitlines() if line.strip().startswith("roughsense ")]
    assert suggested, "the samples' README suggests no command"
    run = "\n".join(blocks("sh"))
    for command in suggested:
        assert command.replace("features.csv", "sample-features.csv") in run, command
