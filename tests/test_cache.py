"""The cache owns only what it made (_util/cache.py, issue 44 D16): the built-in study is found, reused and replaced
by the key its builder wrote into it (``.roughsense-cache-key``), checked with lstat for type and owner. A folder
the builder did not make is never deleted, whatever its name."""
from __future__ import annotations

import os
import shutil
import warnings

import pytest

from roughsense._util import atomic
from roughsense._util.cache import KEY_FILE, cached_folder, folder_entry, key_files, made_here
from roughsense.errors import RoughsenseWarning

STEM = "simulated-study-seed3"


def complete(root):
    return (root / ".simulation-complete").is_file()


def user_study(folder):
    """What ``roughsense simulate --out`` leaves: a study with the completion marker (and no cache key)."""
    (folder / "images").mkdir(parents=True)
    (folder / "study.toml").write_text("[simulation]\nseed = 3\n")
    (folder / ".simulation-complete").write_text("seed = 3\n")
    (folder / "images" / "mine.png").write_bytes(b"mine")
    return folder


@pytest.fixture
def cache(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    root.mkdir(mode=0o700)
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(root))
    return root


@pytest.fixture
def built():
    calls = []

    def build(root, keys):
        with atomic.staged_folder(root) as staging:
            for name, text in keys.items():
                (staging / name).write_text(text)
            (staging / ".simulation-complete").write_text("built\n")
        calls.append(root)

    return build, calls


def snapshot(folder):
    return sorted((str(p.relative_to(folder)), p.read_bytes() if p.is_file() and not p.is_symlink() else None)
                  for p in folder.rglob("*"))


def get(version, build):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        root = cached_folder(STEM, version, build, is_complete=complete)
    return root, [str(w.message) for w in caught if issubclass(w.category, RoughsenseWarning)]


def test_the_builder_marks_its_entry_and_reuses_and_replaces_only_that(cache, built):
    build, calls = built
    first, said = get("v1", build)
    assert first == folder_entry(STEM, "v1") and (first / KEY_FILE).read_text() == f"{STEM}-v1\n" and not said
    assert made_here(first, first.name) and get("v1", build)[0] == first and calls == [first]
    second, _ = get("v2", build)  # a new simulator: the old entry is the cache's own, so it goes
    assert calls == [first, second] and not first.exists() and made_here(second, second.name)


def test_a_users_study_under_the_builders_names_is_never_deleted(cache, built, tmp_path):
    """D16: on 390ce82 every complete simulated-study-seedN-* folder went, with rmtree."""
    build, calls = built
    planted = {
        "user-named": user_study(cache / f"{STEM}-mine"),  # the repro
        "old-version-name": user_study(cache / f"{STEM}-0123456789ab"),
        "copied-entry": user_study(cache / f"{STEM}-copy"),
        "partial-name": user_study(cache / f".{STEM}-v0{atomic.PARTIAL_TAG}999999999-x"),
    }
    (planted["copied-entry"] / KEY_FILE).write_text(f"{STEM}-v0\n")  # a real entry's key, copied under another name
    target = user_study(tmp_path / "elsewhere")
    (cache / f"{STEM}-link").symlink_to(target)  # a link to a user's study
    (target / KEY_FILE).write_text(f"{STEM}-link\n")
    keyed_link = user_study(cache / f"{STEM}-keylink")  # the key itself a link to a real key
    real_key = tmp_path / "key"
    real_key.write_text(f"{STEM}-keylink\n")
    (keyed_link / KEY_FILE).symlink_to(real_key)
    before = {name: snapshot(folder) for name, folder in planted.items()}
    before_target = snapshot(target)
    entry, said = get("v1", build)
    assert calls == [entry] and made_here(entry, entry.name) and not said
    assert {name: snapshot(folder) for name, folder in planted.items()} == before
    assert (cache / f"{STEM}-link").is_symlink() and snapshot(target) == before_target
    assert (keyed_link / "images" / "mine.png").read_bytes() == b"mine"
    get("v2", build)  # and again when a new version replaces the cache's own entry
    assert {name: snapshot(folder) for name, folder in planted.items()} == before and snapshot(target) == before_target
    assert not entry.exists()


@pytest.mark.parametrize("plant", ["study", "link", "foreign-key", "other-key", "key-is-a-folder", "key-is-a-fifo",
                                   "key-with-more", "key-is-a-link"])
def test_a_users_folder_at_the_exact_entry_is_left_and_the_study_built_elsewhere(cache, built, tmp_path, plant):
    build, calls = built
    entry = folder_entry(STEM, "v1")
    if plant == "link":
        entry.symlink_to(user_study(tmp_path / "mine"))
    else:
        user_study(entry)
    if plant == "foreign-key":  # the right key, but the file is another user's (root can give it away)
        (entry / KEY_FILE).write_text(f"{entry.name}\n")
        if os.geteuid() != 0:
            pytest.skip("needs root to give a file to another user")
        os.chown(entry / KEY_FILE, 12345, 12345)
    if plant == "other-key":
        (entry / KEY_FILE).write_text("simulated-study-seed4-v1\n")
    if plant == "key-is-a-folder":
        (entry / KEY_FILE).mkdir()
    if plant == "key-is-a-fifo":  # never opened for reading (it would block): lstat says what it is
        os.mkfifo(entry / KEY_FILE)
    if plant == "key-with-more":
        (entry / KEY_FILE).write_text(f"{entry.name}\n" * 2)
    if plant == "key-is-a-link":
        (tmp_path / "real-key").write_text(f"{entry.name}\n")
        (entry / KEY_FILE).symlink_to(tmp_path / "real-key")
    looked = entry.resolve() if plant == "link" else entry
    before = snapshot(looked)
    root, said = get("v1", build)
    assert root != entry and not root.is_relative_to(cache) and made_here(root, root.name) and calls == [root]
    assert snapshot(looked) == before and (looked / "images" / "mine.png").read_bytes() == b"mine"
    assert len(said) == 1 and str(entry) in said[0] and "not made by roughsense" in said[0]


def test_a_folder_of_another_user_is_not_the_caches(cache, built):
    if os.geteuid() != 0:
        pytest.skip("needs root to give a folder to another user")
    build, calls = built
    entry, _ = get("v1", build)
    os.chown(entry, 12345, 12345)
    assert not made_here(entry, entry.name)
    get("v2", build)
    assert entry.exists()  # not this user's: never deleted, even with the cache's own key in it
    shutil.rmtree(entry)


def test_builtin_study_passes_the_key_to_the_simulator(cache, monkeypatch):
    """cli/_studies.py: the simulator writes the key into the folder it builds (sim/simulate.py ``markers``)."""
    from roughsense.cli import _studies
    from roughsense.sim import simulate as sim

    seen = {}

    def fake(root, *, seed, jobs, force, progress, markers):
        seen.update(markers)
        user_study(root)
        for name, text in markers.items():
            (root / name).write_text(text)
        return root

    monkeypatch.setattr(sim, "simulate_study", fake)
    monkeypatch.setattr(_studies, "simulator_fingerprint", lambda: "v1")
    mine = user_study(cache / "simulated-study-seed3-mine")
    root = _studies.builtin_study(3)
    assert root == folder_entry(STEM, "v1") and seen == key_files(root) and made_here(root, root.name)
    assert (mine / "images" / "mine.png").read_bytes() == b"mine"


def test_simulate_study_writes_its_markers_into_the_study(tmp_path):
    from roughsense.sim.config import SimulationConfig, with_image_size
    from roughsense.sim.simulate import simulate_study

    config = with_image_size(SimulationConfig(pads=("smooth",), specimens=("R2",), forces_n=(2.0,), repetitions=1,
                                              participants=2, sessions=1), 400, 60)
    out = simulate_study(tmp_path / "s", config, seed=3, jobs=1, markers=key_files(tmp_path / "s"))
    assert (out / KEY_FILE).read_text() == "s\n" and made_here(out, "s") and complete(out)


def test_a_link_of_another_user_at_an_old_entry_with_a_partial_beside_it(cache, built, tmp_path):
    """A partial folder of the cache's own beside a link another user planted at its target's name: the link is
    never followed or removed, and the build goes on."""
    if os.geteuid() != 0:
        pytest.skip("needs root to give a link to another user")
    build, calls = built
    (cache / f"{STEM}-v0").symlink_to(user_study(tmp_path / "theirs"))
    os.lchown(cache / f"{STEM}-v0", 12345, 12345)
    partial = cache / f".{STEM}-v0{atomic.PARTIAL_TAG}999999999-x"
    partial.mkdir()
    (partial / KEY_FILE).write_text(f"{STEM}-v0\n")
    entry, _ = get("v1", build)
    assert calls == [entry] and (cache / f"{STEM}-v0").is_symlink() and (tmp_path / "theirs" / "study.toml").exists()
