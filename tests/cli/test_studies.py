"""``builtin`` names the simulated paper study wherever a study folder is accepted; a real folder of that name
is reached as ``./builtin``. The cache entry is faked with a small simulated study at the exact cache path."""
from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

from roughsense.cli._studies import builtin_study_path
from roughsense.io.study import COMPLETE_MARKER
from tests.commands import one_error

SEED = 7


@pytest.fixture(scope="module")
def tiny(simulated_tiny):
    """conftest's shared study, whose seed is SEED (copied before use: the cache below gets its own copy)."""
    assert f"seed = {SEED}" in (simulated_tiny / "study.toml").read_text()
    return simulated_tiny


@pytest.fixture
def cache(tiny, tmp_path, monkeypatch):
    """A cache whose built-in study of seed SEED is the tiny one (so nothing is simulated here)."""
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    from roughsense._util.cache import key_files

    root = builtin_study_path(SEED)
    shutil.copytree(tiny, root)
    for name, text in key_files(root).items():  # as the builder marks the entries it makes
        (root / name).write_text(text)
    assert (root / COMPLETE_MARKER).is_file()
    return root


def test_fit_and_features_take_builtin_with_seed(run_cli, cache, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli("fit", "--study", "builtin", "--seed", SEED, "--pad", "smooth", "--condition", "2N",
                             "--max-components", "2", "--model", "pls", "--out", "m.json")
    assert code == 0, err
    import json

    assert json.loads((tmp_path / "m.json").read_text())["training"]["study_path"] == str(cache)
    code, _, err = run_cli("features", "--study", "builtin", "--seed", SEED, "--out", "f.csv")
    assert code == 0, err
    features = pd.read_csv(tmp_path / "f.csv")
    manifest = pd.read_csv(cache / "manifest.csv")
    assert list(features["image"]) == list(manifest["image"])


@pytest.mark.slow
def test_study_prints_the_folder_it_used(run_cli, cache, tmp_path, monkeypatch, quick_figures):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli("study", "--study", "builtin", "--seed", SEED, "--out", "r", "--max-components", "2",
                             "--no-loso", "--permutations", "0")  # which folder, not the controls, is checked here
    assert code == 0, err
    assert f"Study folder: {cache.resolve()}" in out
    assert "builtin" in out.split("Study folder:")[1].splitlines()[0]
    # The default (no --study) is the same study.
    code, out2, err = run_cli("study", "--seed", SEED, "--out", "r", "--max-components", "2", "--no-loso", "--force",
                              "--permutations", "0")
    assert code == 0, err
    assert f"Study folder: {cache.resolve()}" in out2


def test_a_real_folder_named_builtin_is_reached_as_dot_slash(run_cli, cache, tiny, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    mine = shutil.copytree(tiny, tmp_path / "builtin")
    (mine / "manifest.csv").write_text(
        "\n".join((tiny / "manifest.csv").read_text().splitlines()[:7]) + "\n")  # the first 6 images only
    code, _, err = run_cli("features", "--study", "./builtin", "--out", "mine.csv")
    assert code == 0, err
    assert len(pd.read_csv(tmp_path / "mine.csv")) == 6
    # The bare word is the built-in study, and says so because a folder of that name is here.
    code, _, err = run_cli("features", "--study", "builtin", "--seed", SEED, "--out", "builtin.csv")
    assert code == 0, err
    assert "./builtin" in err
    assert len(pd.read_csv(tmp_path / "builtin.csv")) == len(pd.read_csv(cache / "manifest.csv"))


def test_a_cached_folder_is_built_once_and_replaces_older_versions_and_killed_runs(tmp_path, monkeypatch):
    """_util/cache.cached_folder: a complete entry is reused; another version's complete entry and a killed run's
    partial sibling are removed before a build; an entry of another stem is left alone."""
    from roughsense._util import atomic
    from roughsense._util.cache import KEY_FILE, cached_folder, folder_entry

    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path))
    built = []

    def build(root, keys):
        with atomic.staged_folder(root) as staging:
            for name, text in keys.items():
                (staging / name).write_text(text)
            (staging / "done").write_text("yes")
        built.append(root)

    def get(version):
        return cached_folder("thing-seed1", version, build, is_complete=lambda r: (r / "done").is_file())

    old = get("v1")
    assert built == [old] and old == folder_entry("thing-seed1", "v1") and get("v1") == old and len(built) == 1
    other = tmp_path / "thing-seed12-v1"
    (other / "done").parent.mkdir()
    (other / "done").write_text("yes")
    partial = tmp_path / f".thing-seed1-v0{atomic.PARTIAL_TAG}999999999-x"
    partial.mkdir()
    (partial / KEY_FILE).write_text("thing-seed1-v0\n")  # a killed build marks its partial folder first
    new = get("v2")
    assert built == [old, new] and not old.exists() and not partial.exists() and other.exists()


def test_check_and_calibrate_take_builtin_with_seed(run_cli, cache, tmp_path, monkeypatch):
    """They answered "builtin: study folder not found". calibrate measures the built-in study and prints, but writes
    nothing into the cache's folder (it is rebuilt whenever the simulator changes), saying so."""
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli("check", "builtin", "--seed", SEED)
    assert code == 0, err
    assert "not found" not in err and out.strip()
    toml = (cache / "study.toml").read_bytes()
    code, out, err = run_cli("calibrate", "builtin", "--seed", SEED, "--limit", "6")
    assert code == 0, err
    assert "px/mm measured from" in out and "wrote" not in out
    assert "nothing written" in err
    assert (cache / "study.toml").read_bytes() == toml
    assert [p.name for p in tmp_path.iterdir()] == ["cache"]


def test_builtin_names_a_specimen_set_of_the_twin_cached_under_its_own_name(run_cli, tiny, tmp_path, monkeypatch):
    """``builtin:paper+grooves`` is its own cache entry (the set is in its key; ``builtin:paper`` is ``builtin``), and
    an unknown set is one line naming the sets there are."""
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    from roughsense._util.cache import key_files

    grooves = builtin_study_path(SEED, "paper+grooves")
    assert grooves != builtin_study_path(SEED) == builtin_study_path(SEED, "paper")
    assert grooves.name.startswith(f"simulated-study-paper-grooves-seed{SEED}-")
    shutil.copytree(tiny, grooves)
    for name, text in key_files(grooves).items():
        (grooves / name).write_text(text)
    code, _, err = run_cli("features", "--study", "builtin:paper+grooves", "--seed", SEED, "--out", "f.csv")
    assert code == 0, err
    assert list(pd.read_csv(tmp_path / "f.csv")["image"]) == list(pd.read_csv(grooves / "manifest.csv")["image"])
    line = one_error(run_cli, "check", "builtin:grooves", "--seed", SEED)
    assert "'builtin:grooves': unknown specimen set 'grooves' (expected one of paper, paper+grooves" in line


def test_a_builtin_set_is_the_caches_not_a_folder_of_inputs():
    from roughsense.cli._common import run_inputs

    assert run_inputs("a.csv", study="builtin:paper+grooves") == run_inputs("a.csv", study="builtin") == [
        Path("a.csv")]


def test_a_builtin_set_without_the_reference_is_refused_before_any_simulation(run_cli):
    line = one_error(run_cli, "check", "builtin:circular", "--seed", SEED)
    assert "'builtin:circular': the set circular lacks the reference R3" in line and "paper+grooves" in line
