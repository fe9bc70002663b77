"""The cache owns only what it made (_util/cache.py, issue 44 D16): the built-in study is found, reused and replaced
by the key its builder wrote into it (``.roughsense-cache-key``), checked with lstat for type and owner. A folder
the builder did not make is never deleted, whatever its name."""
from __future__ import annotations

import os
import shutil
import warnings
from pathlib import Path

import pytest

from roughsense._util import atomic
from roughsense._util.cache import KEY_FILE, cached_folder, folder_entry, key_files, made_here
from roughsense.errors import RoughsenseWarning
from tests.as_user import AS_ROOT, NOBODY, as_nobody, needs_root

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

    def fake(root, config=None, *, seed, jobs, force, progress, markers):
        seen.update(markers)
        seen["config"] = config
        user_study(root)
        for name, text in markers.items():
            (root / name).write_text(text)
        return root

    monkeypatch.setattr(sim, "simulate_study", fake)
    monkeypatch.setattr(_studies, "simulator_fingerprint", lambda: "v1")
    mine = user_study(cache / "simulated-study-seed3-mine")
    root = _studies.builtin_study(3)
    assert seen.pop("config") is None  # the paper's study: the simulator's defaults
    assert root == folder_entry(STEM, "v1") and seen == key_files(root) and made_here(root, root.name)
    assert (mine / "images" / "mine.png").read_bytes() == b"mine"
    # A set of the twin's is its own entry, simulated on that set; the paper's entry stays.
    grooves = _studies.builtin_study(3, specimen_set="paper+grooves")
    assert seen.pop("config").specimens == ("paper+grooves",) and seen == key_files(grooves)
    assert grooves.name == "simulated-study-paper-grooves-seed3-v1" and made_here(root, root.name)


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


def _poison(root: Path, key: str) -> None:
    """Write a well-formed, correctly checksummed entry under ``key``, as anyone who can write ``root`` can."""
    import hashlib

    (root / "features").mkdir(parents=True, exist_ok=True)
    body = b"image,f\na.png,999\n"
    (root / "features" / f"{key}.csv").write_bytes(body + b"#sha256=" + hashlib.sha256(body).hexdigest().encode()
                                                   + b"\n")


def _cached(monkeypatch, root: Path):
    import pandas as pd

    from roughsense._util import cache

    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(root))
    monkeypatch.setattr(cache, "_BYPASS_SAID", set())
    with pytest.warns(Warning) as caught:
        first = cache.cached_frame("k" * 24, lambda: pd.DataFrame({"image": ["a.png"], "f": [1.0]}))
        second = cache.cached_frame("k" * 24, lambda: pd.DataFrame({"image": ["a.png"], "f": [1.0]}))
    return first, second, [str(w.message) for w in caught]


@needs_root
def test_a_cache_made_by_another_user_is_bypassed_with_one_warning(shared, monkeypatch):
    """36.4: another user created the shared cache folder and planted an entry: study reported its numbers."""
    root = shared / "cache"
    assert as_nobody(lambda: (root.mkdir(mode=0o755), _poison(root, "k" * 24))) == "ok"
    (frame, cached), (again, cached_again), said = _cached(monkeypatch, root)
    assert frame["f"].tolist() == [1.0] and not cached and again["f"].tolist() == [1.0] and not cached_again
    assert len(said) == 1 and "belongs to another user" in said[0] and str(root) in said[0]


def test_a_cache_others_can_write_is_bypassed_and_a_new_one_is_private(tmp_path, monkeypatch):
    """36.4 (the rule): a group- or world-writable cache is not read; a cache roughsense creates is 0700."""
    root = tmp_path / "cache"
    root.mkdir()
    os.chmod(root, 0o777)
    _poison(root, "k" * 24)
    (frame, cached), _, said = _cached(monkeypatch, root)
    assert frame["f"].tolist() == [1.0] and not cached
    assert len(said) == 1 and "can be written by other users" in said[0]
    from roughsense._util import cache

    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "fresh"))
    assert cache.usable_cache_dir() == tmp_path / "fresh"
    assert (tmp_path / "fresh").stat().st_mode & 0o777 == 0o700


@pytest.mark.skipif(not AS_ROOT, reason="a file of another user's needs root to make")
def test_a_cache_entry_swapped_after_its_check_is_not_trusted(tmp_path, monkeypatch):
    """36.4, the window the lstat checks leave: an entry that another user swaps in between ``foreign_reason``'s
    lstat and the read (through a cache root whose parent they can write) was read as results."""
    import pandas as pd

    from roughsense._util import cache

    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    mine, theirs = pd.DataFrame({"image": ["a.png"], "x": [1.0]}), pd.DataFrame({"image": ["a.png"], "x": [99.0]})
    cache.cached_frame("other", lambda: theirs)  # a well-formed entry, its checksum right, to plant as "mine"
    root = cache.usable_cache_dir()
    planted = tmp_path / "planted.csv"
    planted.write_bytes((root / "features" / "other.csv").read_bytes())
    os.chown(planted, NOBODY, NOBODY)
    cache.cached_frame("mine", lambda: mine)
    checked = cache.foreign_reason

    def check_then_swap(path, *, folder):
        reason = checked(path, folder=folder)
        if not folder and path.name == "mine.csv":
            os.replace(planted, path)  # the swap lands just after the check
        return reason

    monkeypatch.setattr(cache, "foreign_reason", check_then_swap)
    frame, was_cached = cache.cached_frame("mine", lambda: mine)
    assert not was_cached and frame["x"].tolist() == [1.0]


def test_a_cache_in_a_folder_others_may_write_without_the_sticky_bit_is_bypassed(tmp_path, monkeypatch):
    """36.4: the cache folder was checked, not the folder it lies in; where others may write that one (a shared
    project folder, mode 0777), they can rename the cache away and put their own in its place between two looks
    (the built-in study then built into, and read from, their folder)."""
    from roughsense._util import cache
    from roughsense.errors import RoughsenseWarning

    shared = tmp_path / "shared"
    shared.mkdir()
    os.chmod(shared, 0o777)
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(shared / "cache"))
    with pytest.warns(RoughsenseWarning, match=f"lies in {shared}, which other users can write without the sticky"):
        assert cache.usable_cache_dir() is None
    os.chmod(shared, 0o1777)  # as /tmp: only an entry's owner may rename it
    assert cache.usable_cache_dir() == shared / "cache"
