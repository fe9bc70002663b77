"""The public API as its users meet it: numpydoc sections on every name in ``roughsense.__all__``, their examples
run as doctests, ``dir(roughsense)`` and tab completion, the API reference built without a warning, and README's
Python snippet run as written.

Sections required. A function: Parameters, Returns, Examples. A class: Parameters and Examples (calling a class
returns the instance, so it has no Returns); each public method it defines: Returns, and Parameters when it takes
any. ``__version__`` is a string, with nothing to document. Examples run in an empty temporary folder (they may
write a study or a model file there), each docstring on its own with no names given: it imports what it uses.
"""
from __future__ import annotations

import doctest
import inspect
import os
import re
import rlcompleter
import subprocess
import sys
from pathlib import Path

import pytest

import roughsense

REPO = Path(__file__).resolve().parents[1]
PUBLIC = [name for name in roughsense.__all__ if name != "__version__"]
#: The calls from images to perceived roughness, in the order a newcomer makes them: the API opens with them.
NEWCOMER = ["simulate_study", "read_study", "analyse_study", "load_model", "predict"]
SECTION = "{0}\n{1}\n"


def _has(doc: str, section: str) -> bool:
    return SECTION.format(section, "-" * len(section)) in doc


def _public_methods(cls: type) -> dict[str, object]:
    """Methods the class itself defines for users (not private ones, nor scikit-learn's generated set_*_request)."""
    methods = {}
    for name, value in vars(cls).items():
        if name.startswith("_") or re.fullmatch(r"set_\w+_request", name):
            continue
        if isinstance(value, (classmethod, staticmethod)):
            value = value.__func__
        if inspect.isfunction(value):
            methods[name] = value
    return methods


def _takes_arguments(function) -> bool:
    return any(name not in ("self", "cls") for name in inspect.signature(function).parameters)


@pytest.mark.parametrize("name", PUBLIC)
def test_numpydoc_sections(name):
    obj = getattr(roughsense, name)
    doc = inspect.getdoc(obj) or ""
    wanted = ["Parameters", "Examples"] + ([] if inspect.isclass(obj) else ["Returns"])
    missing = [section for section in wanted if not _has(doc, section)]
    if inspect.isclass(obj):
        for method_name, method in _public_methods(obj).items():
            method_doc = inspect.getdoc(method) or ""
            needed = ["Returns"] + (["Parameters"] if _takes_arguments(method) else [])
            missing += [f"{method_name}: {section}" for section in needed if not _has(method_doc, section)]
    assert not missing, f"{name} lacks {missing}"


@pytest.mark.parametrize("name", PUBLIC)
def test_examples_run(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    obj = getattr(roughsense, name)
    tests = [t for t in doctest.DocTestFinder().find(obj, name, globs={}) if t.examples]
    assert tests, f"{name} has no example"
    flags = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE
    runner = doctest.DocTestRunner(optionflags=flags)
    report: list[str] = []
    for test in tests:
        runner.run(test, out=report.append)
    assert runner.failures == 0, "".join(report)


def test_dir_and_tab_completion_show_the_public_api():
    listed = dir(roughsense)
    assert set(roughsense.__all__) <= set(listed)
    assert not [name for name in listed if name.startswith("_") and not name.endswith("__")], listed
    assert "importlib" not in listed and "annotations" not in listed
    completer = rlcompleter.Completer({"rs": roughsense})
    offered = set()
    for state in range(100):
        match = completer.complete("rs.S", state)
        if match is None:
            break
        offered.add(match.rstrip("("))
    assert {"rs.SIMPLS", "rs.SpatialSpectrum", "rs.SpreadModel", "rs.StudyWriter"} <= offered


def test_api_reference_builds_without_warnings(tmp_path):
    """``make docs`` runs the same command (into build/api)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(roughsense.__file__).parents[1]),
                                                         os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-m", "pdoc", "--docformat", "numpy", "--output-directory", str(tmp_path),
                           "roughsense"], capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0 and not done.stderr.strip(), done.stderr
    page = (tmp_path / "roughsense.html").read_text(encoding="utf-8")
    assert [name for name in PUBLIC if f'id="{name}"' not in page] == []
    assert page.count('<h6 id="examples">Examples</h6>') >= len(PUBLIC)  # the numpydoc sections were understood
    members = re.findall(r'<section id="(\w+)">', page)
    assert members[:len(_newcomer_calls())] == _newcomer_calls()  # the page's members follow __all__
    assert _in_order(page[:page.index('<section id="')], NEWCOMER)  # and its text opens with all five


def _newcomer_calls() -> list[str]:
    """The five calls, as __all__ opens."""
    return NEWCOMER


def _in_order(text: str, names: list[str]) -> bool:
    at = [text.find(f"{name}(") for name in names]
    return -1 not in at and at == sorted(at)


def test_the_api_and_its_help_open_with_the_five_calls():
    """``__all__``, the module docstring's numbered list and ``help(roughsense)`` all start with the five calls."""
    import pydoc

    assert roughsense.__all__[:len(_newcomer_calls())] == _newcomer_calls()
    numbered = re.findall(r"^(\d)\. ``(\w+)\(", roughsense.__doc__, flags=re.M)
    assert numbered == [(str(i), name) for i, name in enumerate(NEWCOMER, 1)]
    text = pydoc.render_doc(roughsense, renderer=pydoc.plaintext)
    opening = text[text.index("DESCRIPTION"):text.index("Then the estimators")]  # before any other name
    assert _in_order(opening, NEWCOMER)


def _readme_snippet() -> str:
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    section = readme.split("\n## Python API\n", 1)[1]
    (snippet,) = re.findall(r"^```python\n(.*?)^```$", section.split("\n## ", 1)[0], flags=re.S | re.M)
    return snippet


def test_readme_snippet_runs_as_written_and_again(tmp_path):
    """A reader runs it, changes a line and runs it again: the second run replaces the first study."""
    (tmp_path / "snippet.py").write_text(_readme_snippet(), encoding="utf-8")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(roughsense.__file__).parents[1]),
                                                         os.environ.get("PYTHONPATH", "")])}
    manifests = []
    for _ in range(2):
        done = subprocess.run([sys.executable, "snippet.py"], cwd=tmp_path, capture_output=True, text=True, env=env,
                              timeout=300)
        assert done.returncode == 0, done.stderr
        manifests.append((tmp_path / "my-study" / "manifest.csv").read_bytes())
    assert manifests[0] == manifests[1] and manifests[0].count(b"\n") == 11  # a header and the 10 images
