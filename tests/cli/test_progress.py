"""Progress off a terminal: one line per stage longer than ~2 s on stderr, nothing for quick ones, and errors
still on a line of their own (the one-line error contract)."""
from __future__ import annotations

import re
import time

import pytest

from roughsense.cli import _common, main
from roughsense.errors import InputError

#: Not a timing check: how long a stage waits for its start line before the test goes on (and fails on its output).
HANG_GUARD_S = 60


def _until_announced() -> None:
    """Until the stage's start line is out. The timer writes it 5 ms after the start (``announce_at_once``), but a
    busy machine may run the timer's thread much later than that: waiting for it keeps the stage a long one however
    late it comes. A line that never comes (written only at the end) fails the test on what it reads."""
    deadline = time.monotonic() + HANG_GUARD_S
    while not _common._open and time.monotonic() < deadline:
        time.sleep(0.005)


def _slow(n: int, delay_s: float = 0.03, *, announced: bool = True):
    """``n`` items ``delay_s`` apart; the first one only once the stage's line is out (``announced``, off a terminal)."""
    for i in range(n):
        time.sleep(delay_s)
        if i == 0 and announced:
            _until_announced()
        yield i


@pytest.fixture
def announce_at_once(monkeypatch):
    monkeypatch.setattr(_common, "ANNOUNCE_AFTER_S", 0.005)


def test_a_long_stage_is_one_line_with_its_duration(announce_at_once, capsys):
    assert list(_common.progress(_slow(4), total=4, description="simulating")) == [0, 1, 2, 3]
    err = capsys.readouterr().err
    assert re.fullmatch(r"roughsense: simulating \(4\) \.\.\. done in \d+\.\d s\n", err), err


def test_a_running_stage_is_announced_before_it_ends_with_its_count(announce_at_once, capsys):
    """The start line is written while the stage is still running (from a timer), not when it ends."""
    seen = []
    for _ in _common.progress(_slow(3, 0.2), total=3, description="controls, 199 shufflings per model"):
        seen.append(capsys.readouterr().err)
    assert seen[0] == "roughsense: controls, 199 shufflings per model (3) ..."
    assert re.fullmatch(r" done in \d+\.\d s\n", capsys.readouterr().err)


def test_a_quick_stage_prints_nothing(capsys):
    assert list(_common.progress(range(100), total=100, description="spectra")) == list(range(100))
    with _common.stage("writing the report"):
        pass
    assert capsys.readouterr().err == ""


def test_a_stage_without_a_count(announce_at_once, capsys):
    with _common.stage("writing the report"):
        time.sleep(0.05)
        _until_announced()
    assert re.fullmatch(r"roughsense: writing the report \.\.\. done in \d+\.\d s\n", capsys.readouterr().err)


def test_a_failing_stage_leaves_the_error_on_its_own_line(announce_at_once, capsys):
    def items():
        yield from _slow(2)
        raise InputError("image file not found", path="study/manifest.csv", row=4)

    # Drive the failure through the CLI's error mapping, as a command would.
    from roughsense.cli import app

    @app.command("_fails_for_test", hidden=True)
    def _fails_for_test() -> None:
        for _ in _common.progress(items(), total=5, description="spectra"):
            pass

    try:
        assert main(["_fails_for_test"]) == 2
    finally:
        app.registered_commands.pop()
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 2, lines
    assert re.fullmatch(r"roughsense: spectra \(5\) \.\.\. stopped after 2 of 5, \d+\.\d s", lines[0]), lines
    assert lines[1].startswith("roughsense: error: study/manifest.csv") and "row 4" in lines[1]


def test_a_warning_inside_a_stage_starts_a_new_line(announce_at_once, capsys):
    from roughsense.cli import _show_warning
    from roughsense.errors import RoughsenseWarning

    for i in _common.progress(_slow(3), total=3, description="cross-validating"):
        if i == 2:
            _show_warning(RoughsenseWarning("participant P3 missed a session"), RoughsenseWarning, "x.py", 1)
    lines = capsys.readouterr().err.splitlines()
    assert lines == ["roughsense: cross-validating (3) ...", "roughsense: warning: participant P3 missed a session"]


def test_on_a_terminal_a_bar_with_count_and_estimate(monkeypatch, capsys):
    import io

    from rich.console import Console

    screen = io.StringIO()
    monkeypatch.setattr(_common, "_interactive", lambda: True)
    monkeypatch.setattr(_common, "_console", lambda: Console(file=screen, force_terminal=True, width=100))
    assert list(_common.progress(_slow(3, announced=False), total=3, description="simulating")) == [0, 1, 2]
    drawn = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", screen.getvalue())
    assert "simulating" in drawn and "3/3" in drawn and "eta" in drawn
    assert capsys.readouterr().err == ""  # the bar, not the log line
