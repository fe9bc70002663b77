"""Force input: the scale line format, typed forces, and a pseudo-terminal standing in for a serial scale."""
from __future__ import annotations

import contextlib
import io
import os
import threading
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs
from hypothesis import strategies as st

from roughsense.errors import ConfigError, InputError
from roughsense.rig.scale import (
    STANDARD_GRAVITY,
    ManualForce,
    SerialScale,
    _Retry,
    open_force_input,
    parse_scale_line,
    parse_typed_force,
)
from tests.commands import HANG_GUARD_S

G = 9.80665  # standard gravity, CGPM 1901 (exact by definition)


class TTYInput(io.StringIO):
    """Typed input that claims to be a terminal, so bad values are asked again instead of refused."""

    def isatty(self) -> bool:
        return True


# --------------------------------------------------------------------------- line format


def test_standard_gravity_is_the_defined_value():
    assert STANDARD_GRAVITY == G


@given(
    grams=hs.decimals(min_value="0.1", max_value="2000", places=2),
    flag=hs.sampled_from(["", "ST,", "ST,GS,", "ST ", "ST, NT, "]),
    sign=hs.sampled_from(["", "+", "+ "]),
    pad_width=hs.integers(1, 9),
    space=hs.sampled_from(["", " ", "  "]),
    eol=hs.sampled_from(["", "\r\n", "\n"]),
)
def test_grams_become_newtons_whatever_the_framing(grams, flag, sign, pad_width, space, eol):
    number = f"{grams:.2f}".rjust(pad_width, "0")
    reading = parse_scale_line(f"{flag}{sign}{number}{space}g{eol}".encode())
    assert reading is not None and reading.stable
    assert reading.force_n == pytest.approx(float(grams) * G / 1000.0, rel=1e-12)


@pytest.mark.parametrize(
    ("line", "force_n", "stable"),
    [
        ("ST,+0.2040kg", 0.204 * G, True),
        ("US,+00150.0 g", 0.150 * G, False),
        ("OL,+9999.9 g", 9.9999 * G, False),
        ("1.003 N", 1.003, True),
        ("2005 mN", 2.005, True),
        ("-0.4g", -0.0004 * G, True),
        (".5 N", 0.5, True),
    ],
)
def test_units_sign_and_stability(line, force_n, stable):
    reading = parse_scale_line(line)
    assert reading.force_n == pytest.approx(force_n, rel=1e-12)
    assert reading.stable is stable


@pytest.mark.parametrize("line", ["", "204.0", "ST,+204.0", "204.0 lb", "Scale v1.2 ready", "ST,+20", "+2x04 g", "12 g 3"])
def test_lines_that_are_not_readings_are_skipped(line):
    assert parse_scale_line(line) is None


def test_typed_force_units_and_blank_takes_the_nominal():
    assert parse_typed_force("", 2.0) == 2.0
    assert parse_typed_force("  2.01 ", 2.0) == 2.01
    assert parse_typed_force("205 g", 2.0) == pytest.approx(0.205 * G)
    assert parse_typed_force("0.3kg", 3.0) == pytest.approx(0.3 * G)
    for bad in ("abc", "2,0", "nan", "inf"):
        with pytest.raises(_Retry):
            parse_typed_force(bad, 2.0)


# --------------------------------------------------------------------------- manual


def test_manual_refuses_a_non_number_when_piped():
    manual = ManualForce(stdin=io.StringIO("abc\n"), prompt_out=io.StringIO())
    with pytest.raises(InputError, match=r"force 'abc' is not a number") as info:
        manual.read_force(2.0, low_n=1.5, high_n=2.5)
    assert str(info.value).startswith("<stdin>: ")


def test_manual_asks_again_on_a_terminal():
    prompts = io.StringIO()
    manual = ManualForce(stdin=TTYInput("abc\n7\n2.2\n"), prompt_out=prompts)
    assert manual.read_force(2.0, low_n=1.5, high_n=2.5) == 2.2
    text = prompts.getvalue()
    assert text.count("set 2 N") == 3
    assert "'abc' is not a number" in text and "7 N is outside 1.5..2.5 N" in text


def test_manual_closed_stdin_is_an_input_error():
    manual = ManualForce(stdin=io.StringIO(""), prompt_out=io.StringIO())
    with pytest.raises(InputError, match="stdin closed"):
        manual.read_force(1.0, low_n=0.5, high_n=1.5)


def test_force_input_spec():
    assert isinstance(open_force_input("manual"), ManualForce)
    for bad in ("scale", "serial:", "serial::9600"):
        with pytest.raises(ConfigError):
            open_force_input(bad)
    with pytest.raises(InputError, match="cannot open the scale's serial port"):
        open_force_input("serial:/dev/does-not-exist-rs:9600")


# --------------------------------------------------------------------------- serial over a pseudo-terminal


#: ``timeout_s`` where the scale does answer (a line every 10 ms): never reached, so a busy machine that runs the
#: writer's thread late cannot turn the reading into a timeout; the timeouts tested are 0.3 s, on silent scales.
SUCCESS_TIMEOUT_S = 30


@pytest.fixture
def pty_scale():
    """A pseudo-terminal: the test writes scale lines to the master, the code reads the slave path."""
    master, slave = os.openpty()
    os.set_blocking(master, False)  # a full pty buffer must not block the writer (and the teardown join)
    stop = threading.Event()
    threads: list[threading.Thread] = []

    def stream(lines: list[bytes], period_s: float = 0.01) -> None:
        def run():
            while not stop.is_set():
                for line in lines:
                    with contextlib.suppress(BlockingIOError):
                        os.write(master, line)
                time.sleep(period_s)

        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        threads.append(thread)

    yield os.ttyname(slave), stream
    stop.set()
    for thread in threads:
        thread.join()
    os.close(master)
    os.close(slave)


def test_serial_takes_the_first_stable_reading(pty_scale):
    path, stream = pty_scale
    stream([b"US,+00150.0 g\r\n", b"noise\r\n", b"ST,+00204.0 g\r\n"])
    prompts = io.StringIO()
    scale = open_force_input(f"serial:{path}:19200", timeout_s=SUCCESS_TIMEOUT_S, stdin=io.StringIO("\n"), prompt_out=prompts)
    with scale:
        assert isinstance(scale, SerialScale)
        assert scale._port.baudrate == 19200
        force = scale.read_force(2.0, low_n=1.5, high_n=2.5, label="[R3] ")
    assert force == pytest.approx(0.204 * G, rel=1e-12)
    assert "[R3] set 2 N on the stage, then press Enter" in prompts.getvalue()


def test_serial_silent_port_times_out(pty_scale):
    path, _ = pty_scale
    with SerialScale(path, timeout_s=0.3, stdin=io.StringIO("\n"), prompt_out=io.StringIO()) as scale:
        with pytest.raises(InputError, match=r"the scale sent nothing for 0.3 s") as info:
            scale.read_force(1.0, low_n=0.5, high_n=1.5)
    assert str(info.value).startswith(f"{path}: ")


def test_serial_never_stable_names_the_last_line(pty_scale):
    path, stream = pty_scale
    stream([b"US,+00101.0 g\r\n"])
    with SerialScale(path, timeout_s=0.3, stdin=io.StringIO("\n"), prompt_out=io.StringIO()) as scale:
        with pytest.raises(InputError, match=r"no stable reading .* within 0.3 s \(last line: 'US,\+00101.0 g'\)"):
            scale.read_force(1.0, low_n=0.5, high_n=1.5)


def test_serial_reading_out_of_range_is_refused_when_piped(pty_scale):
    path, stream = pty_scale
    stream([b"ST,+00050.0 g\r\n"])
    with SerialScale(path, timeout_s=SUCCESS_TIMEOUT_S, stdin=io.StringIO("\n"), prompt_out=io.StringIO()) as scale:
        with pytest.raises(InputError, match=r"0.4903 N is outside 1.5..2.5 N"):
            scale.read_force(2.0, low_n=1.5, high_n=2.5)


# --------------------------------------------------------------------------- --timeout-s bounds every read (issue 22)


def within(seconds, call):
    """Run ``call`` in a thread; (finished in time?, its result or exception). A hang fails, never blocks the suite."""
    outcome = {}

    def run():
        try:
            outcome["value"] = call()
        except Exception as exc:  # handed back to the test
            outcome["value"] = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(seconds)
    return not thread.is_alive(), outcome.get("value")


def test_serial_bytes_without_line_ends_time_out(pty_scale):
    path, stream = pty_scale
    stream([b"0123456789"])  # a steady stream that never ends a line (a wrong baud rate looks like this)
    with SerialScale(path, timeout_s=0.3, stdin=io.StringIO("\n"), prompt_out=io.StringIO()) as scale:
        # A hang guard, not a speed bound: 200 times the timeout, so a busy machine cannot trip it.
        done, error = within(60, lambda: scale.read_force(1.0, low_n=0.5, high_n=1.5))
        assert done, "the read ignored --timeout-s"
    assert isinstance(error, InputError)
    text = str(error)
    assert text.startswith(f"{path}: the scale sent bytes but no line end within 0.3 s (got '0123")
    assert len(text) < len(path) + 200


def test_serial_runaway_line_is_dropped_and_the_next_reading_taken(pty_scale):
    path, stream = pty_scale
    stream([b"#" * 5000 + b"\r\nST,+00204.0 g\r\n"])
    with SerialScale(path, timeout_s=SUCCESS_TIMEOUT_S, stdin=io.StringIO("\n"), prompt_out=io.StringIO()) as scale:
        done, force = within(10 * SUCCESS_TIMEOUT_S, lambda: scale.read_force(2.0, low_n=1.5, high_n=2.5))
        assert done, "the read waited for a line end past --timeout-s"
    assert force == pytest.approx(0.204 * G, rel=1e-12)


def test_serial_carriage_return_alone_ends_a_line(pty_scale):
    path, stream = pty_scale
    stream([b"US,+00150.0 g\r", b"ST,+00204.0 g\r"])
    with SerialScale(path, timeout_s=SUCCESS_TIMEOUT_S, stdin=io.StringIO("\n"), prompt_out=io.StringIO()) as scale:
        done, force = within(10 * SUCCESS_TIMEOUT_S, lambda: scale.read_force(2.0, low_n=1.5, high_n=2.5))
        assert done, "the read waited for a line end past --timeout-s"
    assert force == pytest.approx(0.204 * G, rel=1e-12)


def test_serial_unstable_runaway_line_is_quoted_short(pty_scale):
    path, stream = pty_scale
    stream([b"US," + b"9" * 200 + b" g\n"])
    with SerialScale(path, timeout_s=0.3, stdin=io.StringIO("\n"), prompt_out=io.StringIO()) as scale:
        with pytest.raises(InputError, match=r"no stable reading .* \(last line: 'US,9+\.\.\.\)$") as info:
            scale.read_force(1.0, low_n=0.5, high_n=1.5)
    assert len(str(info.value)) < len(path) + 200


def test_typed_force_quotes_a_huge_entry_short():
    with pytest.raises(_Retry) as info:
        parse_typed_force("x" * 1_000_000, 2.0)
    assert len(str(info.value)) < 200


def test_capture_with_a_scale_streaming_no_line_ends_stops_at_timeout(tmp_path, pty_scale):
    """The command, as an operator runs it: ``--timeout-s 1`` ends the run in seconds with one line, exit 2."""
    import subprocess
    import sys

    from tests.videos import write_video

    path, stream = pty_scale
    stream([b"+00102.0"])
    video = write_video(tmp_path / "camera.avi")
    args = [sys.executable, "-c", "from roughsense.cli import run; run()",
            "capture", "--source", str(video), "--out", str(tmp_path / "study"),
            "--specimen", "R3", "--pad", "fp", "--roi", "auto", "--shape", "rectangular", "--wavelength-mm", "3",
            "--forces-from", f"serial:{path}", "--timeout-s", "1"]
    try:
        run = subprocess.run(args, input="\n", capture_output=True, text=True, timeout=300)  # a hang guard
    except subprocess.TimeoutExpired:
        pytest.fail("capture ignored --timeout-s while the scale streamed bytes with no line end")
    assert run.returncode == 2, run.stderr
    last = run.stderr.strip().splitlines()[-1]
    assert last.startswith(f"roughsense: error: {path}: the scale sent bytes but no line end within 1 s")
    assert "Traceback" not in run.stderr


@pytest.mark.parametrize("typed, hint", [("1_0", "no '_' between digits"), ("\u0662", "write the digits 0-9")])
def test_a_typed_force_is_spelled_as_every_number_roughsense_reads(typed, hint):
    """float() would take 1_0 as 10 N and an Arabic-Indic two as 2 N; the one number parser refuses both."""
    with pytest.raises(_Retry, match=hint):
        parse_typed_force(typed, 2.0)


def test_a_scale_line_with_digits_of_another_script_is_not_a_reading():
    assert parse_scale_line("ST,GS +\u0662\u0660\u0665 g") is None
    assert parse_scale_line("ST,GS +205 g").force_n == pytest.approx(0.205 * 9.80665)


@pytest.mark.parametrize("typed, grams", [("1e2 g", 100.0), ("100 g", 100.0), ("1.0e-1 kg", 100.0), ("+1E2G", 100.0)])
def test_a_typed_force_with_a_unit_takes_every_spelling_a_number_may_have(typed, grams):
    """Issue 28.16: 100 g was accepted and 1e2 g refused; both are read by the one number parser."""
    assert parse_typed_force(typed, 2.0) == pytest.approx(grams * 9.80665 / 1000)


@pytest.mark.parametrize("typed, hint", [("1_0 g", "no '_' between digits: write 10"), ("\u0662 kg", "write the digits 0-9")])
def test_a_typed_force_with_a_unit_is_refused_with_the_numbers_hint(typed, hint):
    with pytest.raises(_Retry, match=hint):
        parse_typed_force(typed, 2.0)


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


class _StreamingPort:
    """A serial port that hands out ``chunks`` (in reads of at most ``size`` bytes), then streams digits forever."""

    def __init__(self, chunks: list[bytes]) -> None:
        self.pending = b"".join(chunks)

    in_waiting = 7

    def reset_input_buffer(self) -> None:
        pass

    def read(self, size: int = 1) -> bytes:
        if not self.pending:
            return b"0" * size  # never a line end, never silent: the case a per-read timeout cannot end
        piece, self.pending = self.pending[:size], self.pending[size:]
        return piece


@pytest.mark.slow
@settings(max_examples=40, deadline=None)
@given(chunks=st.lists(st.one_of(st.binary(max_size=300), st.sampled_from([b"\r\n", b"\r", b"\n", b"ST,+00204.0 g",
                                                                            b"US,+1 kg", b"+1e400 g"])), max_size=30))
def test_whatever_a_scale_sends_the_read_ends_within_its_timeout(chunks):
    """On the reader's own clock (a fake one, a millisecond per look): no wall-clock bound, which a loaded
    machine would break, yet a read that ignored its deadline would never end or read past it."""
    import types
    from unittest import mock

    from roughsense.errors import InputError
    from roughsense.rig import scale as scale_module

    clock = types.SimpleNamespace(now=0.0)

    def monotonic() -> float:
        clock.now += 0.001
        return clock.now

    port = _StreamingPort(chunks)
    reads = []
    port_read = port.read
    port.read = lambda size=1: reads.append(size) or port_read(size)
    scale = scale_module.SerialScale.__new__(scale_module.SerialScale)  # the reader without a real port
    scale.name, scale.timeout_s, scale._port, scale._serial_error = "COM9", 0.05, port, OSError
    with mock.patch.object(scale_module, "time", types.SimpleNamespace(monotonic=monotonic)):
        try:
            reading = scale.read_stable()
        except InputError as exc:
            assert str(exc).startswith("COM9: ") and len(str(exc)) < 300
        else:
            assert np.isfinite(reading.force_n) and reading.stable
    assert len(reads) <= 50  # one read per look at the clock, none after its 0.05 s
