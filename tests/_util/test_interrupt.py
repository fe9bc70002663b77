"""_util/interrupt.py: a signal is a request, honoured at the next safe point, never swallowed."""
from __future__ import annotations

import os

import pytest

from tests.commands import grating_png


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

    def signalled(spectrum, paths, *rest):
        os.kill(os.getpid(), number)  # arrives while the spectra are computed; the run goes on to its commit
        return real(spectrum, paths, *rest)

    monkeypatch.setattr(features, "_image_features", signalled)
    code, out, err = run_cli("features", image, "-o", tmp_path / "x.csv")
    assert code == 128 + number and err == "roughsense: interrupted\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.png"]
