"""Every command's --help reads whole in a standard 80-column terminal: wrapped, never cut with an ellipsis."""
from __future__ import annotations

import re

import pytest

from roughsense import __version__
from roughsense.cli import app, main


def _commands() -> list[str]:
    import typer.main

    group = typer.main.get_command(app)
    return sorted(group.commands)


def test_every_command_is_listed():
    # The list below is discovered, so a new command is checked without editing this test.
    assert {"study", "features", "fit", "predict", "simulate"} <= set(_commands())


@pytest.mark.parametrize("command", [None, *_commands()])
def test_help_fits_80_columns(command, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    monkeypatch.delenv("LINES", raising=False)
    args = ["--help"] if command is None else [command, "--help"]
    assert main(args) == 0
    text = re.sub(r"\x1b\[[0-9;]*m", "", capsys.readouterr().out)  # colour, if the environment forces it
    lines = text.splitlines()
    assert len(lines) > 5 and "Usage: roughsense" in text
    too_long = [line for line in lines if len(line) > 80]
    assert not too_long, f"{len(too_long)} line(s) over 80 columns, e.g. {too_long[0]!r}"
    cut = [line for line in lines if "…" in line]  # rich marks a cut cell with a one-character ellipsis
    assert not cut, f"help cut short: {cut[0]!r}"


def test_simulate_help_shows_the_whole_spec_syntax(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    assert main(["simulate", "--help"]) == 0
    text = capsys.readouterr().out
    for spec in ("rect:WAVELENGTH[:DEPTH[:RIDGE_WIDTH]]", "circ:DIAMETER", "sin:WAVELENGTH:AMPLITUDE",
                 "rand:CORRELATION_LENGTH:RMS[:SEED]"):
        assert spec in text


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"roughsense {__version__}"
