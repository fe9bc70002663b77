"""Ctrl-C as a terminal's foreground job receives it, however the test suite itself was started.

A process started in the background (``make test &``, nohup, a CI script without job control) inherits SIGINT
ignored, and so do pytest's workers and every process a test starts; roughsense keeps an ignored SIGINT ignored
(``_util/interrupt.py``: a background run is stopped by SIGTERM). A test of what Ctrl-C does would then see the
signal vanish: the run goes on to its end (exit 0), or a wait for it never ends. A test that sends Ctrl-C gives the
process under test the SIGINT a shell's foreground job has: a child through :func:`sigint_as_in_a_terminal`, this
process (whose handlers a test installs) by setting Python's own handler before ``interrupt.install()``.
"""
from __future__ import annotations

import signal


def sigint_as_in_a_terminal() -> None:
    """``preexec_fn`` of a child a test sends Ctrl-C: SIGINT at its default, as in a foreground job."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)

