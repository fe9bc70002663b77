"""Atomic writes (_util/atomic.py): a refused write names the file the user asked for, never its temporary."""
from __future__ import annotations

import errno
import os
import shutil

import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from roughsense._util import atomic
from roughsense.errors import OutputExistsError, RoughsenseError
from tests.as_user import as_nobody, needs_root
from tests.commands import dead_pid, one_error, refusal_line
from tests.fuzzing import EXAMPLES, FUZZ


def refuse_rename(monkeypatch):
    """What a sticky shared folder does to another user's file (root bypasses it, so it is simulated): the rename
    of the temporary over the target is refused, and the error names the temporary."""
    real = os.replace

    def replace(src, dst, *args, **kwargs):
        if atomic.is_temporary(src):
            raise PermissionError(errno.EPERM, "Operation not permitted", os.fspath(src), os.fspath(dst))
        return real(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "replace", replace)


@pytest.mark.parametrize("write", [lambda p: atomic.write_text(p, "x\n"), lambda p: atomic.write_bytes(p, b"x"),
                                   lambda p: atomic.write_csv(p, __import__("pandas").DataFrame({"a": [1]}))])
def test_a_refused_rename_names_the_file_not_the_temporary(tmp_path, monkeypatch, write):
    target = tmp_path / "study.toml"
    target.write_text("theirs\n")
    refuse_rename(monkeypatch)
    with pytest.raises(RoughsenseError) as info:
        write(target)
    message = str(info.value)
    assert message == f"{target}: cannot write: Operation not permitted"
    assert ".tmp" not in message and info.value.path == target
    assert target.read_text() == "theirs\n" and [p.name for p in tmp_path.iterdir()] == ["study.toml"]


def test_a_refused_temporary_names_the_file(tmp_path, monkeypatch):
    """The temporary itself refused (a folder the user may not write): named as the file asked for."""
    real = os.chmod

    def chmod(path, mode, *args, **kwargs):
        if atomic.is_temporary(path):
            raise PermissionError(errno.EACCES, "Permission denied", os.fspath(path))
        return real(path, mode, *args, **kwargs)

    monkeypatch.setattr(os, "chmod", chmod)
    with pytest.raises(RoughsenseError, match=r"out\.csv: cannot write: Permission denied$") as info:
        atomic.write_text(tmp_path / "out.csv", "x\n")
    assert ".tmp" not in str(info.value)
    assert list(tmp_path.iterdir()) == []


def test_a_folder_that_is_a_file_names_the_file(tmp_path):
    (tmp_path / "shared").write_text("a file, not a folder\n")
    with pytest.raises(RoughsenseError, match=r"shared/out\.csv: cannot write") as info:
        atomic.write_text(tmp_path / "shared" / "out.csv", "x\n")
    assert ".tmp" not in str(info.value)


def test_an_error_about_another_file_keeps_its_own_name(tmp_path):
    """An OSError of another file met inside the write's block is not the write's: it is not renamed."""
    with pytest.raises(FileNotFoundError) as info:
        with atomic.atomic_open(tmp_path / "out.txt") as handle:
            handle.write(open(tmp_path / "missing.txt").read())  # noqa: SIM115
    assert info.value.filename == str(tmp_path / "missing.txt")
    assert list(tmp_path.iterdir()) == []


def test_a_model_file_whose_rename_is_refused_is_named(tmp_path, monkeypatch):
    """A writer above (save_model, as ``fit`` calls it) gets the message naming the model file."""
    import numpy as np

    from roughsense import SIMPLS
    from roughsense.model import modelfile as mf
    from roughsense.sensor.spectrum import SpatialSpectrum

    target = tmp_path / "model.json"
    refuse_rename(monkeypatch)

    rng = np.random.default_rng(0)
    X = rng.random((20, 45))
    model = SIMPLS(2).fit(X, X @ rng.standard_normal(45))
    definition = mf.feature_definition_for(SpatialSpectrum(px_per_mm=20.0, roi=(0, 8, 400, 16)).fit(), ["1N"])
    with pytest.raises(RoughsenseError) as info:
        mf.save_model(target, model, feature_definition=definition, training={})
    assert str(info.value) == f"{target}: cannot write: Operation not permitted"


@needs_root
@pytest.mark.parametrize("kind", ["link", "folder"])
def test_a_retired_folder_planted_by_another_user_is_refused_not_put_back(shared, tmp_path, kind):
    """36.1: a link ``.rep3.roughsense-retired-<dead PID>-abc`` to a private folder became the report folder."""
    private = tmp_path / "private"
    private.mkdir(mode=0o700)
    (private / "results.csv").write_text("mine")
    planted = shared / f".rep3{atomic.RETIRED_TAG}{dead_pid()}-abc"
    plant = (lambda: os.symlink(private, planted)) if kind == "link" else (lambda: os.mkdir(planted))
    assert as_nobody(plant) == "ok"
    with pytest.raises(OutputExistsError) as info, atomic.staged_folder(shared / "rep3") as staging:
        (staging / "results.csv").write_text("report")
    message = str(info.value)
    reason = "is a symbolic link, not a folder" if kind == "link" else "belongs to another user"
    assert reason in message and f"delete {planted}" in message
    assert not (shared / "rep3").exists() and os.path.lexists(planted)
    assert (private / "results.csv").read_text() == "mine" and (private.stat().st_mode & 0o777) == 0o700


def test_a_leftover_that_is_not_a_real_folder_is_never_followed(tmp_path):
    """36.1 (the rule): a leftover's name on a link, even one's own, is refused: lstat decides, not the link's target."""
    private = tmp_path / "private"
    private.mkdir()
    (private / "a.csv").write_text("mine")
    parent = tmp_path / "shared"
    parent.mkdir()
    planted = parent / f".out{atomic.PARTIAL_TAG}{dead_pid()}-abcd"
    planted.symlink_to(private)
    with pytest.raises(OutputExistsError, match="is a symbolic link, not a folder"):
        atomic.clean_leftovers(parent / "out")
    assert (private / "a.csv").read_text() == "mine" and planted.is_symlink()


@needs_root
def test_an_output_link_made_by_another_user_is_not_followed(shared, tmp_path):
    """36.1 (the rule): ``--out S/rep3`` where another user made rep3 a link to the victim's folder."""
    private = tmp_path / "private"
    private.mkdir()
    (private / "a.csv").write_text("mine")
    assert as_nobody(lambda: os.symlink(private, shared / "rep3")) == "ok"
    with pytest.raises(OutputExistsError, match="symbolic link made by another user"):
        atomic.FolderSwap(shared / "rep3")
    assert (private / "a.csv").read_text() == "mine"


def _study_with_an_image_outside_images(tmp_path):
    from tests.analysis.test_dataset import make_study

    root = make_study(tmp_path / "study", pads=("smooth",), repetitions=1)
    first = sorted((root / "images").iterdir())[0]
    (root / "raw").mkdir()
    moved = root / "raw" / first.name
    first.rename(moved)
    manifest = root / "manifest.csv"
    manifest.write_text(manifest.read_text().replace(f"images/{first.name}", f"raw/{first.name}"))
    return root, moved


@pytest.mark.parametrize("command", ["features", "predict", "fit", "study"])
def test_no_output_may_be_an_image_the_manifest_lists_outside_images(run_cli, tmp_path, command):
    """36.2/36.3's rule, "every path a run writes is checked against every path it reads": the inputs of --study
    were its four tables and images/, so `features --study S -o S/raw/x.png --force` replaced a study image that
    the manifest lists at raw/x.png (manifest paths are relative to the folder, anywhere in it)."""
    from tests.commands import LEGACY_MODEL, error_line

    root, image = _study_with_an_image_outside_images(tmp_path)
    before = image.read_bytes()
    out = image.parent if command == "study" else image
    args = {"features": ["features", "--study", root, "-o", out],
            "predict": ["predict", LEGACY_MODEL, "--study", root, "-o", out],
            "fit": ["fit", "--study", root, "--pad", "smooth", "--condition", "2N", "-o", out],
            "study": ["study", "--study", root, "--out", out]}[command]
    code, _, err = run_cli(*args, "--force")
    assert code == 2 and image.read_bytes() == before
    line = error_line(err)
    assert line.startswith(f"roughsense: error: --out {out} is ") and f"{image}; choose another path" in line


def test_an_output_that_is_an_input_is_refused_even_with_force(run_cli, tiny_copy, tmp_path, tiny_model_2n):
    """28.15: `ratings r.csv --out r.csv --force` replaced the raw ratings; fit and predict destroyed their inputs."""
    model = tmp_path / "m.json"
    shutil.copy(tiny_model_2n, model)
    image = next((tiny_copy / "images").iterdir())
    cases = [
        (["ratings", tiny_copy / "ratings.csv", "--out", tiny_copy / "ratings.csv"], tiny_copy / "ratings.csv"),
        (["fit", "--study", tiny_copy, "--pad", "smooth", "--condition", "2N", "--out", tiny_copy / "manifest.csv"],
         tiny_copy / "manifest.csv"),
        (["predict", model, image, "--out", model], model),
        (["predict", model, image, "--out", image], image),
        (["predict", model, "--study", tiny_copy, "--out", tiny_copy / "images" / "x.csv"], tiny_copy / "images"),
        (["features", image, "--out", image], image),
        (["features", "--study", tiny_copy, "--out", tiny_copy / "specimens.csv"], tiny_copy / "specimens.csv"),
        (["protocol", "--seed", "1", "--specimens", tiny_copy / "specimens.csv", "--out", tiny_copy / "specimens.csv"],
         tiny_copy / "specimens.csv"),
        (["study", "--study", tiny_copy, "--out", tiny_copy], tiny_copy),
    ]
    for args, victim in cases:
        before = victim.read_bytes() if victim.is_file() else None
        line = one_error(run_cli, *args, "--force")
        assert "--force does not change this" in line and "--out" in line, line
        if before is not None:
            assert victim.read_bytes() == before, args
    link = tmp_path / "link.json"
    link.hardlink_to(model)  # the same file under another name
    line = one_error(run_cli, "predict", model, image, "--out", link, "--force")
    assert f"is an input of this run {model}" in line


def test_a_full_disk_names_the_file_being_written(tmp_path, monkeypatch):
    from roughsense._util import atomic

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(atomic.os, "fsync", full)
    target = tmp_path / "out" / "summary.csv"
    with pytest.raises(RoughsenseError) as info:
        atomic.write_text(target, "a,b\n1,2\n")
    assert str(info.value) == f"{target}: cannot write: No space left on device"
    assert not target.exists() and list(target.parent.iterdir()) == []  # no temporary left behind


def test_a_full_disk_is_one_line_from_the_cli(run_cli, tmp_path, monkeypatch):
    from roughsense._util import atomic

    real_open = atomic.os.fdopen

    class Full:
        def __init__(self, handle):
            self.handle = handle

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.handle.close()

        def write(self, data):
            raise OSError(errno.ENOSPC, "No space left on device")

        def __getattr__(self, name):
            return getattr(self.handle, name)

    monkeypatch.setattr(atomic.os, "fdopen", lambda *a, **k: Full(real_open(*a, **k)))
    ratings = tmp_path / "ratings.csv"
    pd.DataFrame({"participant": ["P01", "P01"], "session": [1, 1], "specimen": ["R2", "R4"],
                  "rating": ["1.0", "0.5"]}).to_csv(ratings, index=False)
    out = tmp_path / "agg.csv"
    code, _, err = run_cli("ratings", ratings, "--out", out)
    assert refusal_line(code, err) == f"roughsense: error: {out}: cannot write: No space left on device"


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.csv"
    with pytest.raises(ZeroDivisionError):
        with atomic.atomic_open(target) as handle:
            handle.write("partial")
            1 / 0
    assert list(tmp_path.iterdir()) == []
    atomic.write_text(target, "whole\n")
    assert target.read_text() == "whole\n"


def test_check_can_write_refuses_existing_without_force(tmp_path):
    target = tmp_path / "model.json"
    target.write_text("{}")
    with pytest.raises(OutputExistsError):
        atomic.check_can_write(target)
    assert atomic.check_can_write(target, force=True) == target


def test_atomic_files_get_the_usual_permissions(tmp_path):
    import os

    umask = os.umask(0o022)
    try:
        path = atomic.write_text(tmp_path / "shared.csv", "a\n")
    finally:
        os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o644


PLANTS = ("own folder", "file", "link to folder", "link to nothing", "fifo")


@pytest.mark.slow
@settings(FUZZ, max_examples=max(40, EXAMPLES // 2))
@given(plant=st.sampled_from(PLANTS), tag=st.sampled_from(("partial", "retired")), target_exists=st.booleans())
def test_a_leftover_is_used_only_when_it_is_the_users_own_folder(tmp_path_factory, plant, tag, target_exists):
    """36.1: whatever sits under a leftover's name, only a real folder of the user's is put back or deleted; anything
    else is refused by name, and what a link points to is never touched."""
    from roughsense._util import atomic
    from roughsense.errors import OutputExistsError

    root = tmp_path_factory.mktemp("plant")
    private = root / "private"
    private.mkdir()
    (private / "a.csv").write_text("mine")
    out = root / "out"
    if target_exists:
        out.mkdir()
        (out / "a.csv").write_text("current")
    child = os.fork()
    if child == 0:  # pragma: no cover - a PID that is surely dead once waited for
        os._exit(0)
    os.waitpid(child, 0)
    name = root / f".out{atomic.PARTIAL_TAG if tag == 'partial' else atomic.RETIRED_TAG}{child}-abcd"
    if plant == "own folder":
        name.mkdir()
        (name / "a.csv").write_text("leftover")
    elif plant == "file":
        name.write_text("x")
    elif plant == "fifo":
        os.mkfifo(name)
    else:
        name.symlink_to(private if plant == "link to folder" else root / "nothing")
    try:
        atomic.clean_leftovers(out)
        refused = None
    except OutputExistsError as exc:
        refused = str(exc)
    assert (refused is None) == (plant == "own folder"), (plant, refused)
    if refused is not None:
        assert f"delete {name}" in refused and os.path.lexists(name)
    else:
        assert not os.path.lexists(name)
        expected = b"current" if target_exists else (b"leftover" if tag == "retired" else None)
        assert (out / "a.csv").read_bytes() == expected if expected else not out.exists()
    assert (private / "a.csv").read_text() == "mine" and sorted(os.listdir(private)) == ["a.csv"]


@pytest.mark.slow
@settings(FUZZ, max_examples=max(40, EXAMPLES // 2))
@given(spelling=st.sampled_from(("same", "dot", "link", "hard link", "parent dots")),
       which=st.sampled_from(("--out", "--plot")))
def test_an_output_spelled_as_any_input_is_refused_whatever_force_says(tmp_path_factory, spelling, which):
    """36.2 (the rule): an output is refused when it names an input by any spelling (./x, a/../x, a link, a hard
    link), --force or not."""
    from roughsense._util.atomic import check_outputs
    from roughsense.errors import ConfigError

    root = tmp_path_factory.mktemp("spell")
    (root / "sub").mkdir()
    image = root / "in.png"
    image.write_bytes(b"x")
    other = {"same": image, "dot": root / "." / "in.png", "parent dots": root / "sub" / ".." / "in.png",
             "link": root / "link.png", "hard link": root / "hard.png"}[spelling]
    if spelling == "link":
        other.symlink_to(image)
    elif spelling == "hard link":
        os.link(image, other)
    outputs = {"--out": root / "x.csv", "--plot": None, which: other}
    with pytest.raises(ConfigError, match=f"{which} .* (an input of this run|is also)"):
        check_outputs(outputs, force=True, inputs=[image])
    assert image.read_bytes() == b"x"
