"""The measured pressing force: typed by the operator, or read from a digital scale over a serial port.

The paper reads a kitchen scale "at the moment each image was captured" (section 2.1). Scales report a
mass; the pad presses with a weight, so grams become newtons with standard gravity.

Scale line format (one reading per line, ending in ``\\r\\n``, ``\\n`` or ``\\r``)::

    [FLAG,]...[sign][number][ ]unit        e.g.  "ST,GS,+00102.35 g"   "US,+0.0512kg"   "1.003 N"   "-0.4g"

- ``unit`` is ``g``, ``kg``, ``N`` or ``mN`` (case-insensitive) and is required: a bare number could be
  grams or newtons, a factor of 100 apart, so it is ignored rather than guessed.
- ``FLAG`` is any two-letter token before the number, separated by commas or spaces. ``ST`` means stable,
  ``US`` unstable, ``OL`` overload. A reading flagged ``US`` or ``OL`` is skipped and the next one waited
  for; a line with no stability flag counts as stable (many scales only stream settled values).
- A line that does not match (a partial line after a buffer flush, a banner) is skipped.
"""
from __future__ import annotations

import math
import re
import sys
import time
from dataclasses import dataclass
from typing import IO, Protocol

from .._util import interrupt
from .._util.checks import short_repr
from ..errors import ConfigError, InputError
from ..io.numbers import SIGN, UNSIGNED_DECIMAL, NumberError, parse_number, spelling_hint

#: Standard gravity (m/s^2): converts a scale's mass reading into the pressing force.
STANDARD_GRAVITY = 9.80665
DEFAULT_BAUD = 9600

_UNIT_TO_N = {"g": STANDARD_GRAVITY / 1000.0, "kg": STANDARD_GRAVITY, "n": 1.0, "mn": 1e-3}
_UNIT = r"(?P<unit>kg|mn|g|n)$"
_READING = re.compile(
    r"^(?P<prefix>(?:[A-Za-z]{2}[\s,]+)*)"  # flags such as ST, US, GS, NT
    rf"(?P<sign>{SIGN})?\s*(?P<number>{UNSIGNED_DECIMAL})\s*{_UNIT}",  # a display shows no exponent
    re.IGNORECASE | re.ASCII,  # the digits 0-9 only, as every number reader of roughsense (io/numbers.py)
)
#: A typed force with its unit: the number before it is read by the one number parser, as a unit-less one is.
_TYPED_UNIT = re.compile(rf"^(?P<number>.*?\S)\s*{_UNIT}", re.IGNORECASE | re.ASCII)
_UNSTABLE_FLAGS = {"US", "OL"}
_LINE_END = re.compile(rb"[\r\n]")
#: Longest line kept while waiting for its end: real readings are under 30 bytes; more is noise or a wrong baud rate.
MAX_LINE_BYTES = 256


@dataclass(frozen=True)
class ScaleReading:
    force_n: float
    stable: bool
    flags: tuple[str, ...]
    raw: str


def parse_scale_line(line: str | bytes) -> ScaleReading | None:
    """Parse one line of a scale's output (format in the module docstring); None if it is not a reading."""
    if isinstance(line, bytes):
        line = line.decode("ascii", errors="replace")
    text = line.strip().strip("\x00").strip()
    match = _READING.match(text)
    if match is None:
        return None
    flags = tuple(f.upper() for f in re.findall(r"[A-Za-z]{2}", match["prefix"]))
    value = float(match["number"]) * _UNIT_TO_N[match["unit"].lower()]
    if match["sign"] == "-":
        value = -value
    return ScaleReading(force_n=value, stable=not (_UNSTABLE_FLAGS & set(flags)), flags=flags, raw=text)


def parse_typed_force(text: str, nominal_force_n: float) -> float:
    """What the operator typed: empty -> the nominal force; "2.01" is newtons; "205 g" / "0.205 kg" convert."""
    text = text.strip()
    if not text:
        return float(nominal_force_n)
    unit = _TYPED_UNIT.match(text)
    number, factor = (unit["number"], _UNIT_TO_N[unit["unit"].lower()]) if unit else (text, 1.0)
    try:  # the one spelling of a number, with or without a unit: 1e2 g is 100 g; no 1_0, no other scripts' digits
        value = float(parse_number(number)) * factor
    except NumberError as exc:
        reading = parse_scale_line(text) if exc.message.startswith("not a number") else None
        if reading is None:
            raise _Retry(f"force {short_repr(text)} is not a number{spelling_hint(number)} (type newtons such as 2.01, "
                         "or 205 g, or 0.205 kg)") from None
        value = reading.force_n
    if not math.isfinite(value):
        raise _Retry(f"force {short_repr(text)} is not a finite number")
    return value


def _shown(raw: bytes) -> str:
    """Bytes from the scale as an error message quotes them: decoded, stripped, at most 60 characters."""
    return short_repr(raw.decode("ascii", errors="replace").strip())


class _LineSplitter:
    """Bytes in, complete non-empty lines out; a line longer than :data:`MAX_LINE_BYTES` is dropped whole.

    ``last`` is the last complete line, ``unended`` the first bytes of a line still waiting for its end (what an
    error message shows when a scale never ends a line).
    """

    def __init__(self) -> None:
        self.pending = b""
        self.overflowed = False  # the current line ran away: drop it up to its end
        self.last: bytes | None = None
        self.unended = b""

    def feed(self, chunk: bytes) -> list[bytes]:
        *ended, self.pending = _LINE_END.split(self.pending + chunk)
        complete = []
        for raw in ended:
            if not self.overflowed and raw:
                complete.append(raw)
            self.overflowed = False
        if len(self.pending) > MAX_LINE_BYTES:
            self.pending, self.overflowed = b"", True
        if complete:
            self.last = complete[-1]
        if len(self.unended) < 64 and len(self.pending) > len(self.unended):
            self.unended = self.pending[:64]
        return complete


class _Retry(Exception):
    """A reading the operator can correct: asked again on a terminal, fatal otherwise."""


class ForceInput(Protocol):
    name: str

    def read_force(self, nominal_force_n: float, *, low_n: float, high_n: float, label: str = "") -> float: ...

    def close(self) -> None: ...


class _OperatorInput:
    """Shared prompting: the operator sets the force, the reading is checked against the step's range."""

    name = "<stdin>"

    def __init__(self, *, stdin: IO[str] | None = None, prompt_out: IO[str] | None = None) -> None:
        self._stdin = stdin
        self._out = prompt_out

    @property
    def stdin(self) -> IO[str]:
        return self._stdin if self._stdin is not None else sys.stdin

    @property
    def out(self) -> IO[str]:
        return self._out if self._out is not None else sys.stderr

    @property
    def interactive(self) -> bool:
        isatty = getattr(self.stdin, "isatty", None)
        return bool(isatty and isatty())

    def ask(self, prompt: str) -> str:
        print(prompt, end="", file=self.out, flush=True)
        with interrupt.immediate():  # Ctrl-C at a prompt stops at once
            line = self.stdin.readline()
        if not line:
            print(file=self.out, flush=True)  # end the prompt line so the error stands on its own
            raise InputError("input ended before the operator answered (stdin closed)", path="<stdin>")
        if not self.interactive:
            print(line.rstrip("\n"), file=self.out, flush=True)  # a log of piped input reads like a session
        return line.rstrip("\r\n")

    def read_force(self, nominal_force_n: float, *, low_n: float, high_n: float, label: str = "") -> float:
        while True:
            try:
                value = self._read_once(nominal_force_n, label)
                if not low_n <= value <= high_n:
                    raise _Retry(
                        f"{value:.4g} N is outside {low_n:.4g}..{high_n:.4g} N, the range for the {nominal_force_n:g} N step"
                    )
                return value
            except _Retry as problem:
                if not self.interactive:
                    raise InputError(str(problem), path=self.name) from None
                print(f"  {problem}; try again", file=self.out, flush=True)

    def _read_once(self, nominal_force_n: float, label: str) -> float:
        raise NotImplementedError

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class ManualForce(_OperatorInput):
    """The operator reads the scale and types the force; Enter alone takes the nominal force."""

    def _read_once(self, nominal_force_n: float, label: str) -> float:
        text = self.ask(f"{label}set {nominal_force_n:g} N, then type the force read (N, or g/kg) "
                        f"[Enter = {nominal_force_n:g}]: ")
        return parse_typed_force(text, nominal_force_n)


class SerialScale(_OperatorInput):
    """A scale streaming readings on a serial port (pyserial). The operator presses Enter once the force is set.

    Readings queued before Enter are flushed, so the value taken is one measured after the force was set.
    """

    def __init__(
        self,
        port: str,
        baud: int = DEFAULT_BAUD,
        *,
        timeout_s: float = 5.0,
        stdin: IO[str] | None = None,
        prompt_out: IO[str] | None = None,
    ) -> None:
        super().__init__(stdin=stdin, prompt_out=prompt_out)
        import serial  # local: only the serial path needs pyserial

        if not timeout_s > 0:
            raise ConfigError(f"--timeout-s must be positive, got {timeout_s:g}")
        self.name = port
        self.timeout_s = float(timeout_s)
        try:
            self._port = serial.Serial(port=port, baudrate=baud, timeout=min(0.25, self.timeout_s))
        except (serial.SerialException, ValueError, OSError) as exc:
            raise InputError(f"cannot open the scale's serial port ({exc})", path=port) from None
        self._serial_error = serial.SerialException

    def _read_once(self, nominal_force_n: float, label: str) -> float:
        self.ask(f"{label}set {nominal_force_n:g} N on the stage, then press Enter to capture: ")
        return self.read_stable().force_n

    def read_stable(self) -> ScaleReading:
        """The first stable reading after flushing queued input; InputError if none arrives within ``timeout_s``.

        Bytes are read as they arrive and split into lines here (never ``readline``, which waits for a line end
        as long as bytes keep coming), so the deadline holds whatever the scale sends: a stream with no line
        ends, a runaway line, or silence.
        """
        lines = _LineSplitter()
        try:
            self._port.reset_input_buffer()
            deadline = time.monotonic() + self.timeout_s
            while time.monotonic() < deadline:
                interrupt.check()  # a safe point: each read lasts at most 0.25 s
                chunk = self._port.read(min(max(1, self._port.in_waiting), MAX_LINE_BYTES))
                for raw in lines.feed(chunk):
                    reading = parse_scale_line(raw)
                    if reading is not None and reading.stable:
                        return reading
        except (self._serial_error, OSError) as exc:
            raise InputError(f"lost the scale's serial port ({exc})", path=self.name) from None
        within = f"within {self.timeout_s:g} s"
        if lines.last is not None:
            raise InputError(f"no stable reading from the scale {within} (last line: {_shown(lines.last)})",
                             path=self.name)
        if lines.unended:
            raise InputError(f"the scale sent bytes but no line end {within} (got {_shown(lines.unended)}; expected "
                             "one reading per line -- check the baud rate)", path=self.name)
        raise InputError(f"the scale sent nothing for {self.timeout_s:g} s (is it on and streaming?)", path=self.name)

    def close(self) -> None:
        self._port.close()


def open_force_input(
    spec: str,
    *,
    timeout_s: float = 5.0,
    stdin: IO[str] | None = None,
    prompt_out: IO[str] | None = None,
) -> ManualForce | SerialScale:
    """``manual`` or ``serial:PORT[:BAUD]`` (e.g. ``serial:/dev/ttyUSB0:9600``)."""
    text = spec.strip()
    if text.lower() == "manual":
        return ManualForce(stdin=stdin, prompt_out=prompt_out)
    if text.lower().startswith("serial:"):
        rest = text[len("serial:"):]
        port, baud = rest, DEFAULT_BAUD
        head, sep, tail = rest.rpartition(":")
        if sep and tail.isdigit():
            port, baud = head, int(tail)
        if not port:
            raise ConfigError(f"--forces-from {short_repr(spec)}: give the port, e.g. serial:/dev/ttyUSB0:9600")
        if baud <= 0:
            raise ConfigError(f"--forces-from {short_repr(spec)}: baud rate must be positive")
        return SerialScale(port, baud, timeout_s=timeout_s, stdin=stdin, prompt_out=prompt_out)
    raise ConfigError(f"--forces-from must be 'manual' or 'serial:PORT[:BAUD]', got {short_repr(spec)}")
