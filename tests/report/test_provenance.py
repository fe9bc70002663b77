"""A study's results are computed once and frozen, and every sentence about where its data came from has one home.

The report and the console render :class:`roughsense.analysis.results.StudyResults`; they must not recompute its
summaries (each costs a pass over every fit) nor reword its provenance (two wordings drift apart)."""
from __future__ import annotations

import dataclasses
import re
import subprocess
from pathlib import Path

import pandas as pd
import pytest

from roughsense.analysis import unseen as unseen_module
from roughsense.analysis.results import Provenance, StudyResults
from roughsense.analysis.study_analysis import analyse_study
from roughsense.model.registry import names as family_names
from roughsense.report import provenance, write_report
from roughsense.report.answer import answer_lines, console_lines
from tests.analysis.test_study_analysis import synthetic_study

SRC = Path(__file__).resolve().parents[2] / "src" / "roughsense"


@pytest.fixture(scope="module")
def small_study():
    study, features = synthetic_study(repetitions=2, seed=5, pads=("smooth",))
    return study, features


def _analyse(study, features, **options):
    return analyse_study(study, features=features, max_components=2, n_permutations=0,
                         conditions=("2N", "combined", "3N"), **options)


@pytest.fixture(scope="module")
def small_analysis(small_study):
    """``_analyse(*small_study)``, once for the module (frozen: the tests only read it)."""
    return _analyse(*small_study)


def test_the_results_are_frozen(small_analysis):
    results = small_analysis
    assert isinstance(results, StudyResults)
    for name in ("fits", "controls", "unseen", "headline_condition", "provenance"):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(results, name, None)
    with pytest.raises(dataclasses.FrozenInstanceError):
        results.provenance.kind = "user"
    assert isinstance(results.fits, tuple)


def test_the_unseen_summary_is_computed_once_per_run(small_study, monkeypatch, tmp_path, quick_figures):
    """analyse_study computes it, the report's four readers and the console read the stored table."""
    calls = []
    real = unseen_module.unseen_summary

    def counting(*stages):
        calls.append(1)
        return real(*stages)

    monkeypatch.setattr(unseen_module, "unseen_summary", counting)
    results = _analyse(*small_study)
    write_report(results, tmp_path / "report")
    lines = console_lines(results)
    assert len(calls) == 1
    assert set(results.unseen["model"]) == set(family_names())
    assert len(results.unseen) == len(family_names()) * 3  # families x conditions
    assert any("combined" in line for line in lines[:1])
    callers = subprocess.run(["grep", "-rn", "unseen_summary(", str(SRC)], capture_output=True, text=True).stdout
    calls_in_code = [line for line in callers.splitlines() if "def unseen_summary" not in line and '"""' not in line
                     and "``" not in line]
    assert [line.split(":")[0].removeprefix(str(SRC)) for line in calls_in_code] == ["/analysis/unseen.py"]


def test_the_headline_condition_is_combined_else_the_last_analysed():
    assert unseen_module.headline_condition(["2N", "combined", "3N"]) == "combined"
    assert unseen_module.headline_condition(("1N", "3N")) == "3N"
    assert unseen_module.headline_condition(pd.Series(["2N", "1N", "2N"])) == "2N"


def test_the_headline_condition_is_stored_and_quoted(small_study, small_analysis):
    study, features = small_study
    with_combined = small_analysis
    assert with_combined.headline_condition == "combined"
    assert "nested leave-one-specimen-out, combined;" in console_lines(with_combined)[0]
    singles = analyse_study(study, features=features, max_components=2, n_permutations=0, conditions=("3N", "1N"))
    assert singles.headline_condition == "1N"
    assert "nested leave-one-specimen-out, 1N;" in console_lines(singles)[0]


def test_without_loso_the_summary_is_empty_and_every_renderer_says_why(small_study):
    results = _analyse(*small_study, cv_schemes=("loo",))
    assert results.unseen.empty
    assert answer_lines(results) == [provenance.NO_LOSO_ANSWER]
    assert console_lines(results)[0] == provenance.NO_LOSO_CONSOLE


class _Folder:
    def __init__(self, simulation=None, synthetic=None):
        self.simulation, self.synthetic = simulation, synthetic


def test_provenance_is_decided_from_the_study_folder():
    simulated = Provenance.of(_Folder({"seed": 7, "ratings_from": "physics", "forces_n": [1, 2]}))
    assert (simulated.kind, simulated.seed, simulated.ratings_from) == ("simulated", 7, "physics")
    assert simulated.settings == {"seed": 7, "ratings_from": "physics", "forces_n": [1, 2]}
    assert Provenance.of(_Folder({})).ratings_from == "paper"  # the simulator's default
    synthetic = Provenance.of(_Folder(synthetic="an example from the twin's images"))
    assert (synthetic.kind, synthetic.note, synthetic.settings) == ("synthetic", "an example from the twin's images", None)
    assert Provenance.of(_Folder()).kind == "user"


def test_each_kind_of_source_is_worded_for_every_renderer():
    simulated, unrecorded = Provenance("simulated", seed=11, ratings_from="paper"), Provenance("simulated")
    synthetic, user = Provenance("synthetic", note="made from the twin"), Provenance("user")
    assert provenance.source_label(simulated, builtin=True) == (
        "simulated: built-in simulated study (digital twin), simulation seed 11")
    assert provenance.source_label(unrecorded, builtin=False).endswith("simulation seed not recorded")
    assert provenance.figure_stamp(simulated) == "SIMULATED DATA (seed 11)"
    assert provenance.figure_stamp(unrecorded) == "SIMULATED DATA (seed ?)"
    assert provenance.figure_stamp(user) is provenance.figure_stamp(synthetic) is None
    assert "made from the twin" in provenance.trust_line(synthetic) and "your images" in provenance.trust_line(user)
    assert provenance.source_paragraphs(user)[0].startswith("This study is user data")
    assert len(provenance.source_paragraphs(simulated)) == 2
    physics = Provenance("simulated", seed=1, ratings_from="physics")
    assert "ratings_from = physics" in provenance.source_paragraphs(physics)[0]
    assert len(provenance.unseen_source_words(physics)) == 2 and len(provenance.unseen_source_words(simulated)) == 1


def test_sentences_about_the_source_live_in_one_module():
    """The grep of issue 38: outside report/provenance.py only the --no-loso option's own definition may match."""
    pattern = re.compile(r"SIMULATED|not measurements|user data|your images|no-loso")
    hits = []
    for folder in (SRC / "report", SRC / "cli"):
        for path in sorted(folder.rglob("*")):
            if path.is_file() and path.suffix in (".py", ".j2") and pattern.search(path.read_text(encoding="utf-8")):
                hits.append(path.relative_to(SRC).as_posix())
    assert hits == ["report/provenance.py", "cli/study_report.py"]
    option_lines = [line for line in (SRC / "cli" / "study_report.py").read_text().splitlines() if pattern.search(line)]
    assert option_lines == ['            False, "--no-loso",']


def test_the_report_and_cli_compare_no_family_name():
    """Families are looked up in the registry (title, marker, colour, paper), never compared by name."""
    files = [*sorted((SRC / "report").glob("*.py")), SRC / "cli" / "study_report.py",
             SRC / "analysis" / "results.py", SRC / "analysis" / "study_analysis.py", SRC / "analysis" / "unseen.py",
             SRC / "analysis" / "signed_rank_tests.py"]
    names = r'"(pls|peak-law|groove)"|PEAK_LAW|GROOVE|\bPLS\b *[!=]=|model ?[!=]= ?PLS'
    run = subprocess.run(["grep", "-nE", names, *map(str, files)], capture_output=True, text=True)
    assert run.stdout == ""


def test_the_study_command_takes_study_and_echoes_what_the_report_package_words(tmp_path, run_cli, monkeypatch,
                                                                                 quick_figures):
    """``study --study DIR`` (the name fit, predict and features use); the console prints report.answer's lines and the
    page's source is report.provenance's label, for a user's folder (no [simulation] table)."""
    from roughsense.io.study import read_study
    from tests.analysis.test_dataset import make_study

    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    folder = make_study(tmp_path / "study", repetitions=2)
    out = tmp_path / "report"
    code, stdout, err = run_cli("study", "--study", folder, "--out", out, "--max-components", "2", "--permutations", "0",
                                "--no-loso")
    assert code == 0, err
    expected = console_lines(analyse_study(read_study(folder), max_components=2, n_permutations=0,
                                           cv_schemes=("loo",)))
    assert stdout.splitlines()[:len(expected)] == expected and expected[0] == provenance.NO_LOSO_CONSOLE
    html = (out / "index.html").read_text(encoding="utf-8")
    assert provenance.source_label(Provenance("user"), builtin=False) in html
    assert provenance.NO_LOSO_ANSWER in html and "SIMULATED" not in html
