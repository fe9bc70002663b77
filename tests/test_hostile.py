"""Issue 36, the fourth hardening pass: no other user's planted file, no FIFO, no signal and no second output path
can lose data, hang a run or change a number. Each test names the item it covers."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from roughsense._util import atomic
from roughsense.errors import OutputExistsError
from tests.as_user import as_nobody
from tests.foreground import sigint_as_in_a_terminal
from tests.sweeps import small_sweep

AS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0
needs_root = pytest.mark.skipif(not AS_ROOT, reason="acting as another user needs root")


def dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


@pytest.fixture()
def shared():
    """A folder every user may write, as /tmp is (pytest's tmp_path is root's alone)."""
    folder = Path(tempfile.mkdtemp(prefix="roughsense-shared-", dir="/tmp"))
    os.chmod(folder, 0o1777)
    yield folder
    shutil.rmtree(folder, ignore_errors=True)


# --------------------------------------------------------------------------- 1. planted retired folder


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


# --------------------------------------------------------------------------- 2, 3. every written path against every read one


def grating_png(path: Path, wavelength_mm: float = 3.0) -> Path:
    import cv2
    import numpy as np

    x_mm = np.arange(1920) / 34.9
    line = 0.5 + 0.35 * np.tanh(3 * np.sin(2 * np.pi * x_mm / wavelength_mm))
    assert cv2.imwrite(str(path), np.tile(np.round(255 * line).astype(np.uint8), (1080, 1)))
    return path


def error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.startswith("roughsense: error: ")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("plot_is", ["the image", "--out"])
def test_features_plot_never_replaces_an_input_or_another_output(run_cli, tmp_path, plot_is):
    """36.2: ``features in.png -o x.csv --force --plot in.png`` replaced the image with the plot."""
    image = grating_png(tmp_path / "in.png")
    before = image.read_bytes()
    plot = {"the image": image, "--out": tmp_path / "x.png"}[plot_is]
    out = tmp_path / ("x.png" if plot_is == "--out" else "x.csv")
    code, _, err = run_cli("features", image, "-o", out, "--force", "--plot", plot)
    assert code == 2 and "--plot" in error_line(err) and "choose another path" in err
    assert image.read_bytes() == before and not out.exists()


def test_ratings_never_replaces_its_specimens_table(run_cli, tmp_path):
    """36.3: ``ratings --specimens FILE -o FILE --force`` replaced the specimens table with the summary."""
    specimens = tmp_path / "specimens.csv"
    specimens.write_text("specimen,shape,wavelength_mm\nR2,rectangular,2\nR3,rectangular,3\n")
    ratings = tmp_path / "ratings.csv"
    ratings.write_text("participant,session,specimen,rating\nP01,1,R2,0.5\nP02,1,R2,0.7\n")
    before = specimens.read_bytes()
    code, _, err = run_cli("ratings", ratings, "--specimens", specimens, "-o", specimens, "--force")
    assert code == 2 and "an input of this run" in error_line(err) and specimens.read_bytes() == before


def test_protocol_sheet_never_replaces_its_specimens_table(run_cli, tmp_path):
    """36.3 (the rule): protocol's --sheet is checked against --specimens too, not only --out."""
    specimens = tmp_path / "specimens.md"
    specimens.write_text("specimen,shape,wavelength_mm\nS1,sinusoidal,1\nS2,sinusoidal,2\nS3,sinusoidal,3\n")
    before = specimens.read_bytes()
    code, _, err = run_cli("protocol", "--seed", 0, "--specimens", specimens, "--reference", "S2",
                           "--out", tmp_path / "s.csv", "--sheet", specimens, "--force")
    assert code == 2 and "--sheet" in error_line(err) and specimens.read_bytes() == before


# --------------------------------------------------------------------------- 4. the cache is trusted only when it is ours


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


# --------------------------------------------------------------------------- 5. a signal is a request, honoured at a safe point


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


def test_sigterm_inside_a_weakref_callback_is_not_swallowed(signals):
    """36.5: SIGTERM raised KeyboardInterrupt inside a weakref callback: printed, ignored, and the run went on."""
    import gc
    import signal
    import weakref

    class Thing:
        pass

    thing = Thing()
    weakref.finalize(thing, os.kill, os.getpid(), signal.SIGTERM)  # the window: a signal during a callback
    del thing
    gc.collect()
    assert signals.requested() == signal.SIGTERM
    with pytest.raises(signals.Interrupted):
        signals.check()


@pytest.mark.parametrize("signum", ["SIGTERM", "SIGINT"])
def test_a_signal_mid_run_commits_nothing_after_it_and_says_interrupted_once(run_cli, tmp_path, monkeypatch, signals,
                                                                            signum):
    """36.5: the run stops at its next safe point: no CSV, one "interrupted" line, exit 143 (SIGTERM) or 130."""
    import signal

    from roughsense.cli import features

    number = getattr(signal, signum)
    image = grating_png(tmp_path / "in.png")
    real = features._image_features

    def signalled(spectrum, paths):
        os.kill(os.getpid(), number)  # arrives while the spectra are computed; the run goes on to its commit
        return real(spectrum, paths)

    monkeypatch.setattr(features, "_image_features", signalled)
    code, out, err = run_cli("features", image, "-o", tmp_path / "x.csv")
    assert code == 128 + number and err == "roughsense: interrupted\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.png"]


# --------------------------------------------------------------------------- 6. only regular files are read


ROUGHSENSE = str(Path(sys.executable).with_name("roughsense"))
LEGACY_MODEL = Path(__file__).parent / "data" / "legacy_models" / "model_2N.json"
HANG_GUARD_S = 300  # not a timing check: on e1630a3 these runs never end, and the suite must


@pytest.mark.parametrize("command", ["predict", "features", "predict-model"])
def test_a_fifo_given_as_an_image_or_a_model_is_refused_at_once(tmp_path, command):
    """36.6: a FIFO as an image hung predict and features (one SIGTERM did not end it)."""
    fifo = tmp_path / ("m.json" if command == "predict-model" else "in.png")
    os.mkfifo(fifo)
    image = fifo if command != "predict-model" else grating_png(tmp_path / "in.png")
    args = {"predict": ["predict", LEGACY_MODEL, image], "features": ["features", image, "-o", tmp_path / "x.csv"],
            "predict-model": ["predict", fifo, image]}[command]
    done = subprocess.run([ROUGHSENSE, *map(str, args)], capture_output=True, text=True, timeout=HANG_GUARD_S,
                          env={**os.environ, "ROUGHSENSE_CACHE_DIR": str(tmp_path / "cache")})
    assert done.returncode == 2
    assert error_line(done.stderr) == f"roughsense: error: {fifo}: is a FIFO (named pipe), not a regular " + (
        "model file; give the model file itself" if command == "predict-model" else
        "image file; give the image file itself")


def test_check_names_a_fifo_in_the_manifest(run_cli, tmp_path):
    """36.6: a FIFO in a manifest was reported as "not found"."""
    from .test_dataset import make_study

    root = make_study(tmp_path / "study", pads=("smooth",), repetitions=1)
    first = sorted((root / "images").iterdir())[0]
    first.unlink()
    os.mkfifo(first)
    code, out, err = run_cli("check", root)
    assert code == 2 and f"image file is a FIFO (named pipe), not a regular image file; give the image file itself: " \
        f"images/{first.name}" in out + err


def test_a_link_to_a_device_is_named_as_a_device(run_cli, tmp_path):
    """Also seen: a symlink to /dev/zero was "image file is empty"."""
    link = tmp_path / "zero.png"
    link.symlink_to("/dev/zero")
    code, _, err = run_cli("features", link, "-o", tmp_path / "x.csv")
    assert code == 2 and error_line(err).endswith(f"{link}: is a device, not a regular image file; give the image "
                                                  "file itself")


@needs_root
def test_check_refuses_an_image_the_user_cannot_read(shared):
    """Also seen: `check` said "study OK" for an image the user cannot read (chmod 000)."""
    import contextlib
    import io

    from roughsense.cli import main

    from .test_dataset import make_study

    root = make_study(shared / "study", pads=("smooth",), repetitions=1)
    for path in [root, *root.rglob("*")]:
        os.chmod(path, 0o755 if path.is_dir() else 0o644)
    first = sorted((root / "images").iterdir())[0]
    os.chmod(first, 0)

    def check_as_nobody() -> str:
        text = io.StringIO()
        with contextlib.redirect_stdout(text), contextlib.redirect_stderr(text):
            code = main(["check", str(root)])
        return f"{code}\n{text.getvalue()}"

    said = as_nobody(check_as_nobody)
    assert said.startswith("2\n") and f"image file cannot be read (permission denied): images/{first.name}" in said


# --------------------------------------------------------------------------- 7. lock files that roughsense did not make


@pytest.mark.parametrize("planted", ["record-fifo", "record-link-to-fifo", "flock-link", "flock-fifo"])
def test_a_planted_lock_file_is_refused_by_name_without_waiting(tmp_path, planted):
    """36.7: a FIFO as ``.NAME.roughsense-lock`` hung the run (and left a 0666 .flock); a symlinked .flock was
    refused with "Too many levels of symbolic links", naming neither the file nor the fix."""
    from roughsense._util.lock import OutputLock, lock_path
    from roughsense.errors import RoughsenseError

    out = tmp_path / "out"
    record = lock_path(out)
    flock = record.with_name(record.name + atomic.FLOCK_SUFFIX)
    target = {"record-fifo": record, "record-link-to-fifo": record, "flock-link": flock, "flock-fifo": flock}[planted]
    if planted.endswith("link"):
        target.symlink_to(tmp_path / "elsewhere")
    elif planted.endswith("link-to-fifo"):
        os.mkfifo(tmp_path / "pipe")
        target.symlink_to(tmp_path / "pipe")
    else:
        os.mkfifo(target)
    # on e1630a3 the record's FIFO blocks here forever: a thread keeps the suite from hanging with it
    import threading

    outcome: list[BaseException | None] = []

    def take() -> None:
        try:
            with OutputLock(out, command="test"):
                outcome.append(None)
        except BaseException as exc:
            outcome.append(exc)

    worker = threading.Thread(target=take, daemon=True)
    worker.start()
    worker.join(HANG_GUARD_S)
    assert outcome and isinstance(outcome[0], RoughsenseError), outcome
    message = str(outcome[0])
    assert f"the lock file {target} is" in message and "delete it" in message
    left = sorted(p.name for p in tmp_path.iterdir())
    assert flock.name not in left or planted.startswith("flock")  # nothing of ours left behind


# --------------------------------------------------------------------------- 8. --roi auto and a non-finite pixel


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
@pytest.mark.parametrize("where", [(0, 0), (599, 999), (10, 500)])
def test_one_non_finite_pixel_outside_the_crop_does_not_move_the_auto_band(bad, where):
    """36.8: a float TIFF with NaN at (0, 0) moved the band (1.29 -> 1.25, unflagged): the crop must be the clean
    image's, and its spectrum identical."""
    import numpy as np

    from roughsense.sensor.line import resolve_roi, spatial_spectrum

    rng = np.random.default_rng(0)
    clean = 0.3 + 0.01 * rng.normal(size=(600, 1000))
    x_px = np.arange(1000)
    clean[400:520] += 0.2 * np.sin(2 * np.pi * x_px / (2.5 * 34.9))  # the one textured band
    dirty = clean.copy()
    dirty[where] = bad
    assert resolve_roi("auto", dirty) == resolve_roi("auto", clean)
    x, y, w, h = resolve_roi("auto", clean)
    assert 370 <= y <= 400 and y + h >= 520
    np.testing.assert_array_equal(spatial_spectrum(dirty, roi="auto"), spatial_spectrum(clean, roi="auto"))


# --------------------------------------------------------------------------- 9, 14, 16. forged model metadata


def _pls_file(tmp_path, training: dict, **section):
    import json

    import numpy as np

    from roughsense import SIMPLS
    from roughsense.model import modelfile as mf
    from roughsense.sensor.spectrum import SpatialSpectrum

    rng = np.random.default_rng(0)
    X = rng.random((30, 45))
    model = SIMPLS(3).fit(X, X @ rng.standard_normal(45) + 5.0)
    path = tmp_path / "model.json"
    definition = mf.feature_definition_for(SpatialSpectrum(px_per_mm=20.0, roi=(0, 8, 400, 16)).fit(), ["1N"])
    mf.save_model(path, model, feature_definition=definition, training={}, force=True)
    document = json.loads(path.read_text())
    document["training"] = training  # forged after writing: save_model refuses to write what loading refuses
    if section:
        document["model"]["applicability"] = {"rotations": np.eye(3, 45).tolist(), "loadings": np.eye(3, 45).tolist(),
                                              "score_var": [1.0, 1.0, 1.0], "t2_limit": 9.0, "q_limit": 1.0,
                                              **section}
    document["sha256"] = mf._digest(document)
    path.write_text(json.dumps(document))
    return path


@pytest.mark.parametrize("stored", [[5e-324, 2.0], [-1.0, 2.0], [0.0, 2.0], [2.0, 1.0], "garbled", [1.0], [1.0, 1e9]])
def test_a_forged_target_range_is_refused_not_ignored_or_underflowed(tmp_path, stored):
    """36.9: ``target_range [5e-324, ...]`` made PLS's floor underflow (roughness 0, interval 0..0); a negative or
    garbled one was silently ignored."""
    from roughsense.errors import ModelFileError
    from roughsense.model.modelfile import load_model

    path = _pls_file(tmp_path, {"study": "s", "target_range": stored})
    with pytest.raises(ModelFileError, match=r"training.target_range"):
        load_model(path)


def test_a_sound_target_range_sets_the_floor_at_half_the_smallest(tmp_path):
    from roughsense.model.modelfile import MIN_ROUGHNESS, load_model

    assert load_model(_pls_file(tmp_path, {"study": "s", "target_range": [0.3, 2.0]})).floor == 0.15
    assert load_model(_pls_file(tmp_path, {"study": "s"})).floor == MIN_ROUGHNESS


@pytest.mark.parametrize("level", [0.5, 0.95, 0.8999, "0.9", True])
def test_an_interval_level_other_than_the_labelled_one_is_refused(tmp_path, level):
    """36.16: an interval level of 0.5 was still labelled pi90 ("90 % interval")."""
    from roughsense.errors import ModelFileError
    from roughsense.model.modelfile import load_model
    from roughsense.model.predict import model_interval

    interval = {"level": level, "trial_log_halfwidth": 0.2, "surface_log_halfwidth": 0.1}
    with pytest.raises(ModelFileError, match=r"training.interval.level: expected 0.9 \(the level roughsense writes "
                                             r"and labels pi90\)"):  # on loading (issue 44), not first on predicting
        load_model(_pls_file(tmp_path, {"study": "s", "interval": interval}))
    interval["level"] = 0.9
    assert model_interval(load_model(_pls_file(tmp_path, {"study": "s", "interval": interval}))).level == 0.9


@pytest.mark.parametrize("level", [0.5, 1e5, 0.9])
def test_an_applicability_level_other_than_the_limits_one_is_refused(tmp_path, level):
    """36.16: nonsense applicability.level values were accepted."""
    from roughsense.errors import ModelFileError
    from roughsense.model.modelfile import load_model

    with pytest.raises(ModelFileError, match="model.applicability.level must be 0.95"):
        load_model(_pls_file(tmp_path, {"study": "s"}, level=level))
    assert load_model(_pls_file(tmp_path, {"study": "s"}, level=0.95)).domain is not None


def _law_file(tmp_path, change) -> Path:
    import json

    import numpy as np

    import roughsense as rs
    from roughsense.model import modelfile as mf

    freq = rs.frequency_grid()
    periods = np.repeat([2.0, 3.0, 4.0, 5.0], 2)
    X = np.exp(-((freq - 1 / periods[:, None]) / 0.05) ** 2) + 0.01
    law = rs.PeakPowerLaw().fit(X, (periods / 3) ** 0.9)
    path = tmp_path / "law.json"
    features = {"spectrum": rs.SpatialSpectrum().feature_definition(), "conditions": ["2N"]}
    mf.save_model(path, law, feature_definition=features, training={"study": "gratings"}, force=True)
    document = json.loads(path.read_text())
    change(document["model"])
    document["sha256"] = mf._digest(document)
    path.write_text(json.dumps(document))
    return path


@pytest.mark.parametrize("box", [(-1000.0, 1000.0), (-700.0, -1.0), (-1.6, 3.0)])
def test_a_forged_peak_law_feature_box_is_refused_in_one_error_without_warnings(tmp_path, box):
    """36.14: a huge feature box was refused only after two RuntimeWarning lines (exp overflow, division by 0)."""
    import warnings

    from roughsense.errors import ModelFileError
    from roughsense.model.modelfile import load_model

    def forge(model):
        model["feature_min"][0], model["feature_max"][0] = box

    path = _law_file(tmp_path, forge)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ModelFileError, match=r"log peak frequency\) must lie within the grid"):
            load_model(path)


@pytest.mark.parametrize("limit", [1e3, -900.0, 51.0])
def test_a_nonsense_clarity_limit_is_refused(tmp_path, limit):
    """36.16: nonsense clarity_limit values were accepted (1e3 flags every spectrum, -900 none)."""
    from roughsense.errors import ModelFileError
    from roughsense.model.modelfile import load_model

    def forge(model):
        model["clarity_limit"] = limit

    with pytest.raises(ModelFileError, match="model.clarity_limit must be"):
        load_model(_law_file(tmp_path, forge))
    assert load_model(_law_file(tmp_path, lambda model: None)).clarity_limit_ is not None


# --------------------------------------------------------------------------- 12. CSV formula injection


FORMULAS = ["=HYPERLINK(\"evil\")", "+cmd", "-2+3", "@SUM(A1)", "\t=1"]


@pytest.mark.parametrize("name", FORMULAS)
def test_an_image_name_a_spreadsheet_would_run_is_written_as_text(run_cli, tmp_path, monkeypatch, name):
    """36.12: image names starting with = + - @ went as they are into predict and features CSVs."""
    import csv

    monkeypatch.chdir(tmp_path)
    image = grating_png(Path(f"{name}.png"))
    code, _, err = run_cli("features", "-o", tmp_path / "features.csv", "--", image)
    assert code == 0, err
    code, _, err = run_cli("predict", "-o", tmp_path / "predict.csv", "--", LEGACY_MODEL, image)
    assert code == 0, err
    for table in ("features.csv", "predict.csv"):
        with open(tmp_path / table, newline="", encoding="utf-8") as handle:
            cell = next(csv.DictReader(handle))["image"]
        assert cell == f"'{image}" and not cell.startswith(("=", "+", "-", "@", "\t", "\r"))


def test_spreadsheet_safety_leaves_numbers_and_plain_text_alone():
    """36.12 (the rule): numbers written as text (predict's 3-digit values) keep their sign; only formulas change."""
    import pandas as pd

    from roughsense._util.text import spreadsheet_safe

    frame = pd.DataFrame({"image": ["a.png", "=1+1", "-x", "\r@y"], "low": ["-0.5", "+3", "-", "nan"],
                          "value": [1.0, -2.0, 3.0, 4.0]})
    safe = spreadsheet_safe(frame)
    assert safe["image"].tolist() == ["a.png", "'=1+1", "'-x", "'\r@y"]
    assert safe["low"].tolist() == frame["low"].tolist() and safe["value"].tolist() == [1.0, -2.0, 3.0, 4.0]
    assert spreadsheet_safe(frame.iloc[:1]) is not None and frame["image"].tolist()[1] == "=1+1"  # no side effect


# --------------------------------------------------------------------------- 10. a pixel budget per figure


@pytest.mark.parametrize("size_in", [(15.0, 9.0), (8.0, 5.6), (25.2, 12.0)])
def test_the_highest_dpi_stays_within_the_pixel_budget_of_a_figure(size_in):
    """36.10: --dpi 1200, the documented maximum, took 3.5 GB and 110 s on a 108-image study."""
    import io
    import warnings

    import matplotlib.pyplot as plt
    from PIL import Image

    from roughsense.report import figures

    fig, ax = plt.subplots(figsize=size_in)
    ax.plot([0, 1], [0, 1])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        png = figures.figure_bytes(fig, "png", dpi=1200)
    width, height = Image.open(io.BytesIO(png)).size
    assert width * height <= figures.MAX_FIGURE_PIXELS
    assert width * height >= 0.5 * figures.MAX_FIGURE_PIXELS  # the tight bbox trims the margins, no more
    assert len(caught) == 1 and "--dpi 1200" in str(caught[0].message)


def test_a_figure_within_the_budget_is_drawn_at_the_dpi_asked():
    import io

    import matplotlib.pyplot as plt

    from roughsense.report import figures

    def draw():
        fig, ax = plt.subplots(figsize=(6.0, 4.0))
        ax.plot([0, 1], [1, 0])
        return fig

    from PIL import Image

    direct = io.BytesIO()
    fig = draw()
    fig.savefig(direct, format="png", dpi=300, bbox_inches="tight", metadata={"Software": None})
    plt.close(fig)
    ours, theirs = (Image.open(io.BytesIO(png)) for png in (figures.figure_bytes(draw(), "png", dpi=300), direct.getvalue()))
    assert ours.info["dpi"] == pytest.approx((300, 300), abs=0.01)  # pHYs stores dots per metre
    # matplotlib's tight box and ours (the ink plus the same pad) agree within 0.03 in: text boxes hold their
    # glyphs' ascent and descent, the ink only the glyphs
    assert all(abs(a - b) <= 0.03 * 300 for a, b in zip(ours.size, theirs.size))


def test_the_dpi_help_states_the_budget_in_force(run_cli):
    from roughsense.report.figures import MAX_FIGURE_PIXELS

    code, out, _ = run_cli("study", "--help")
    assert code == 0 and f"within {MAX_FIGURE_PIXELS / 1e6:g} Mpx" in " ".join(out.split())


# --------------------------------------------------------------------------- 11. a large sweep shows its estimate


def _big_sweep(tmp_path, seeds: int) -> Path:
    path = tmp_path / "sweep.toml"
    path.write_text(small_sweep(range(seeds), max_components=4))
    return path


def test_a_sweep_beyond_the_confirmation_size_shows_its_estimate_and_needs_yes(run_cli, tmp_path, monkeypatch):
    """36.11: explore started a grid of 10,100 cells (about 6 hours) with no estimate, cap or confirmation."""
    from roughsense.explore import sweep as sweep_module

    path = _big_sweep(tmp_path, sweep_module.CONFIRM_CELLS + 1)
    code, _, err = run_cli("explore", path, "--out", tmp_path / "out", "--jobs", 1)
    frames = (sweep_module.CONFIRM_CELLS + 1) * 5 * 3 * 2  # cells x specimens x the default 3 forces x repetitions
    hours = frames * sweep_module.CELL_SECONDS_PER_FRAME / 3600
    assert code == 2 and error_line(err) == (
        f"roughsense: error: {path}: {sweep_module.CONFIRM_CELLS + 1} cells, about {hours:.1f} core-hours "
        f"({hours:.1f} h on 1 worker): a sweep of more than {sweep_module.CONFIRM_CELLS} cells runs only with --yes")
    assert not (tmp_path / "out").exists()
    ran = []
    monkeypatch.setattr("roughsense.explore.runner.run_sweep", lambda *a, **k: ran.append(a) or 1 / 0)
    code, _, err = run_cli("explore", path, "--out", tmp_path / "out", "--jobs", 1, "--yes")
    assert ran and f"roughsense: {sweep_module.CONFIRM_CELLS + 1} cells, about {hours:.1f} core-hours" in err


def test_a_sweep_within_the_confirmation_size_needs_no_yes(tmp_path):
    from roughsense.explore.sweep import CONFIRM_CELLS, check_size_confirmed, read_sweep

    assert check_size_confirmed(read_sweep(_big_sweep(tmp_path, CONFIRM_CELLS)), yes=False, workers=2) is None


def test_the_explore_docs_state_the_confirmation_size_in_force():
    from roughsense.explore.sweep import CELL_SECONDS_PER_FRAME, CONFIRM_CELLS

    text = (Path(__file__).parents[1] / "docs" / "explore.md").read_text()
    assert f"more than {CONFIRM_CELLS:,} cells" in text and CELL_SECONDS_PER_FRAME == 6.7 / 420


# --------------------------------------------------------------------------- 13, 15. explore: Ctrl-C and a killed run's scratch


@pytest.mark.parametrize("how", ["Ctrl-C", "kill"])
def test_ctrl_c_during_explore_is_one_interrupted_line_and_no_dask_traceback(tmp_path, how):
    """36.13: Ctrl-C (SIGINT to the whole process group, as a terminal sends it) printed a 30-line Dask traceback
    and no "interrupted" line; SIGTERM to roughsense alone let its workers log their heartbeats' failure. The window
    is forced: the signal is sent once a cell has been written."""
    import signal
    import time

    sweep = _big_sweep(tmp_path, 60)
    out = tmp_path / "out"
    run = subprocess.Popen([ROUGHSENSE, "explore", str(sweep), "--out", str(out), "--jobs", "1"],
                           stderr=subprocess.PIPE, text=True, start_new_session=True,
                           preexec_fn=sigint_as_in_a_terminal,  # a terminal's job, however pytest was started
                           env={**os.environ, "ROUGHSENSE_CACHE_DIR": str(tmp_path / "cache")})
    try:
        deadline = time.monotonic() + HANG_GUARD_S  # a guard against a hang, not a timing check
        while not any((out / "results").glob("*.parquet")) and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        if how == "Ctrl-C":
            os.killpg(run.pid, signal.SIGINT)
        else:
            os.kill(run.pid, signal.SIGTERM)
        _, err = run.communicate(timeout=HANG_GUARD_S)
    finally:
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
    assert run.returncode == (130 if how == "Ctrl-C" else 143), err
    assert "Traceback" not in err and "distributed" not in err
    assert [line for line in err.splitlines() if "interrupted" in line] == ["roughsense: interrupted"]
    assert not list(out.glob(".dask-scratch.*"))


def test_a_killed_sweeps_scratch_folder_is_removed_by_the_next_run(tmp_path):
    """36.15: after kill -9 and a resumed explore, ``.dask-scratch.*.tmp/`` stayed in the finished folder."""
    from roughsense.explore import runner

    out = tmp_path / "out"
    dead = out / f".dask-scratch.{dead_pid()}.abcd1234.tmp"
    legacy = out / ".dask-scratch.abcd1234.tmp"  # named before the PID was in it
    live = out / f".dask-scratch.{os.getppid()}.efgh5678.tmp"
    for folder in (dead, legacy, live):
        (folder / "worker-x").mkdir(parents=True)
    fresh = runner._scratch(out)
    assert fresh.name.startswith(f".dask-scratch.{os.getpid()}.") and atomic.is_temporary(fresh)
    assert sorted(p.name for p in out.iterdir()) == sorted([live.name, fresh.name])


# --------------------------------------------------------------------------- Also seen


def test_a_jpeg_exif_orientation_does_not_rotate_the_pixels(tmp_path):
    """Also seen: a JPEG with EXIF orientation 6 was rotated while the same pixels in a PNG (eXIf chunk) were not."""
    import numpy as np
    from PIL import Image

    from roughsense.io.images import read_image

    rng = np.random.default_rng(0)
    pixels = np.repeat(np.repeat(rng.integers(0, 256, (12, 20), dtype=np.uint8), 8, axis=0), 8, axis=1)  # 96 x 160
    exif = Image.Exif()
    exif[0x0112] = 6  # rotate 90 degrees clockwise to display
    Image.fromarray(pixels).save(tmp_path / "a.jpg", quality=100, exif=exif)
    Image.fromarray(pixels).save(tmp_path / "a.png", exif=exif)
    jpeg, png = read_image(tmp_path / "a.jpg"), read_image(tmp_path / "a.png")
    assert jpeg.shape == png.shape == pixels.shape
    np.testing.assert_array_equal(png, pixels)
    assert np.abs(jpeg.astype(int) - pixels).mean() < 2  # the same picture, to JPEG's loss


def test_same_surface_refuses_one_image_given_twice(run_cli, tmp_path):
    """Also seen: ``--same-surface`` with one image twice counted 2 trials (a narrower surface interval)."""
    image = grating_png(tmp_path / "a.png")
    (tmp_path / "link.png").symlink_to(image)
    code, _, err = run_cli("predict", LEGACY_MODEL, image, tmp_path / "link.png", "--same-surface")
    assert code == 2 and error_line(err) == (f"roughsense: error: --same-surface: {tmp_path / 'link.png'} is the same "
                                             f"file as {image}; give each press once")


@pytest.mark.parametrize("name", ["a\x1b[31mred", "line\nbreak", "x" * 201])
def test_a_sweep_name_is_one_printable_line_of_bounded_length(tmp_path, name):
    """Also seen: a sweep name with control characters went raw into the page's <title>; 100,000 characters were
    accepted."""
    import json

    from roughsense.errors import ConfigError
    from roughsense.explore.sweep import MAX_NAME_CHARS, read_sweep

    path = _big_sweep(tmp_path, 1)
    text = path.read_text().replace("[sweep]\n", f"[sweep]\nname = {json.dumps(name)}\n")
    path.write_text(text)
    with pytest.raises(ConfigError, match=f"at most {MAX_NAME_CHARS} printable characters"):
        read_sweep(path)


def test_two_decimal_commas_are_two_problems_not_four_or_a_pandas_error(run_cli, tmp_path):
    """Also seen: a decimal-comma row was reported twice, the second time as a raw pandas "C error"; and "run
    `roughsense check` again" omitted the folder."""
    from .test_dataset import make_study

    root = make_study(tmp_path / "study", pads=("smooth",), repetitions=1)
    lines = (root / "manifest.csv").read_text().splitlines()
    lines[1] = lines[1].replace(".", ",", 1)  # force 1,0116...: one field too many
    lines[3] = lines[3].replace(".", ",", 1) + ",5"  # images/x,png and a trailing value: two too many
    (root / "manifest.csv").write_text("\n".join(lines) + "\n")
    code, out, err = run_cli("check", root)
    listed = out.splitlines()
    assert code == 2 and len(listed) == 2, out
    assert listed[0].startswith(f"{root / 'manifest.csv'}, row 2: 6 fields but the header has 5")
    assert listed[1].startswith(f"{root / 'manifest.csv'}, row 4: 7 fields but the header has 5")
    assert error_line(err).endswith(f"2 problems (listed above); fix them and run `roughsense check {root}` again")


def test_study_on_a_missing_folder_does_not_suggest_checking_it(run_cli, tmp_path):
    """Also seen: ``study --study missing`` suggested running check on the missing folder."""
    code, _, err = run_cli("study", "--study", tmp_path / "missing", "--out", tmp_path / "rep")
    assert code == 2 and error_line(err) == f"roughsense: error: {tmp_path / 'missing'}: study folder not found"


def test_a_link_in_place_of_a_sweeps_results_folder_is_refused(tmp_path):
    """36.1 (the rule, explore): results/ as a link would send every cell's file into the folder it points to."""
    from roughsense.explore.store import ResultStore
    from roughsense.explore.sweep import read_sweep

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    out = tmp_path / "out"
    out.mkdir()
    (out / "results").symlink_to(elsewhere)
    with pytest.raises(OutputExistsError, match="results in it is not a folder roughsense made"):
        ResultStore(out, read_sweep(_big_sweep(tmp_path, 1)), force=True)
    assert list(elsewhere.iterdir()) == []


def test_ctrl_c_at_an_operators_prompt_stops_at_once(signals):
    """36.5 (the rule, where a run waits on a person): a prompt is no safe point that ever comes, so a signal there
    stops the run at once, as Python's own Ctrl-C did, rather than after the operator answers."""
    import io
    import signal
    import threading
    import time

    from roughsense.rig.scale import ManualForce

    read, write = os.pipe()
    stdin = os.fdopen(read, "r")
    done = threading.Event()

    def press_ctrl_c() -> None:
        time.sleep(0.2)  # whether it lands before or during the wait, the outcome is the same
        os.kill(os.getpid(), signal.SIGINT)
        if not done.wait(HANG_GUARD_S):  # on a regression: an answer ends the wait, and the test fails on its value
            os.write(write, b"2\n")

    helper = threading.Thread(target=press_ctrl_c, daemon=True)
    helper.start()
    try:
        with pytest.raises(signals.Interrupted):
            ManualForce(stdin=stdin, prompt_out=io.StringIO()).read_force(2.0, low_n=1.5, high_n=2.5)
    finally:
        done.set()
        helper.join()
        stdin.close()
        os.close(write)


@pytest.mark.parametrize("signum", ["SIGINT", "SIGTERM"])
def test_ctrl_c_ends_a_live_display_as_its_normal_end_and_sigterm_stops_the_run(signals, signum):
    """36.5: live scoring ends with Ctrl-C (its summary is the result); a SIGTERM there still stops the run."""
    import io
    import signal

    from rich.console import Console

    from roughsense.rig.live import render_live

    def frames():
        for i in range(10**9):
            if i == 3:
                os.kill(os.getpid(), getattr(signal, signum))
            yield float(i), 1.0 + i
    summary = render_live(frames(), console=Console(file=io.StringIO()))
    assert summary.updates == 3 and summary.last_score == 3.0
    assert signals.requested() == (None if signum == "SIGINT" else signal.SIGTERM)


def test_a_fifo_as_a_video_source_is_refused_at_once(tmp_path):
    """36.6 (the rule, the rig): OpenCV would block opening a FIFO given as a video file."""
    from roughsense.errors import InputError
    from roughsense.rig.camera import open_source

    os.mkfifo(tmp_path / "run.avi")
    with pytest.raises(InputError, match="is a FIFO \\(named pipe\\), not a regular video file"):
        open_source(tmp_path / "run.avi")
