"""One command-line style: usage errors are one line like every other error, --debug goes anywhere, flags are
flags, --jobs means one thing, and --version/--help start without the numerical stack."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import typer.main

from roughsense.cli import app
from roughsense.errors import InputError


def _commands() -> dict:
    return typer.main.get_command(app).commands


def _one_line_error(code: int, err: str) -> str:
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith("roughsense: error: ")
    assert not any(mark in err for mark in ("╭", "│", "Usage:", "Traceback"))
    return lines[0]


@pytest.mark.parametrize(("args", "named"), [
    (["study", "--no-such-option"], "--no-such-option"),
    (["--no-such-option"], "--no-such-option"),
    (["no-such-command"], "no-such-command"),
    (["fit", "--pad", "smooth"], "--study"),              # a missing required option
    (["explore", "--out", "x"], "SWEEP.toml"),            # a missing argument
    (["fit", "--seed", "three"], "--seed"),               # a value of the wrong type
    (["study", "--out"], "--out"),                        # an option without its value
    (["study", "extra"], "extra"),                        # an unexpected argument
])
def test_a_usage_error_is_one_line_naming_the_option_exit_2(run_cli, args, named):
    code, out, err = run_cli(*args)
    line = _one_line_error(code, err)
    assert named in line and out == ""
    if args[0] in _commands():  # says where to read more, for the command the user typed
        assert f"roughsense {args[0]} --help" in line


def test_no_arguments_still_shows_the_help(run_cli):
    code, out, err = run_cli()
    assert code == 2 and "Usage: roughsense" in out and "study" in out


@pytest.fixture
def failing_command():
    """A hidden command that fails with a user error, as a real one does on a bad file."""
    @app.command("_fails", hidden=True)
    def _fails() -> None:
        raise InputError("bad value", path="ratings.csv", row=3)

    yield "_fails"
    app.registered_commands[:] = [c for c in app.registered_commands if c.name != "_fails"]


@pytest.mark.parametrize("where", ["before", "after"])
def test_debug_before_or_after_the_command_shows_the_traceback(run_cli, failing_command, where):
    args = ["--debug", failing_command] if where == "before" else [failing_command, "--debug"]
    code, _, err = run_cli(*args)
    assert code == 2 and "Traceback" in err and "roughsense: error: ratings.csv, row 3: bad value" in err
    code, _, err = run_cli(failing_command)  # and not in the next run
    _one_line_error(code, err)


def test_debug_is_offered_in_the_help(run_cli):
    code, out, _ = run_cli("--help")
    assert code == 0 and "--debug" in out and "after the command" in " ".join(out.split())


@pytest.mark.parametrize("command", [None, *sorted(_commands())])
def test_flags_show_no_type_in_the_help(run_cli, command, monkeypatch):
    monkeypatch.setenv("COLUMNS", "100")
    code, out, _ = run_cli(*(["--help"] if command is None else [command, "--help"]))
    assert code == 0 and "--help" in out
    for metavar in ("<bool>", "BOOLEAN", "<boolean>"):
        assert metavar not in out


def _jobs_options() -> dict:
    return {name: next(p for p in command.params if p.name == "jobs")
            for name, command in _commands().items() if any(p.name == "jobs" for p in command.params)}


def test_jobs_is_one_option_with_one_default_on_every_command():
    options = _jobs_options()
    assert {"study", "features", "fit", "predict", "simulate"} <= set(options)
    assert {tuple(o.opts) for o in options.values()} == {("--jobs", "-j")}
    assert {o.help for o in options.values()} == {options["study"].help}
    assert {o.default for o in options.values()} == {None}  # omitted: every core this process may use
    assert "all cores" in options["study"].help


def test_jobs_omitted_is_every_usable_core_and_zero_is_refused(run_cli):
    from roughsense._util.workers import usable_cores

    expected = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert usable_cores() == expected
    for command in ("study", "simulate", "fit"):
        code, _, err = run_cli(command, "--jobs", "0")
        assert "--jobs" in _one_line_error(code, err)


HEAVY = ("numpy", "pandas", "scipy", "sklearn", "matplotlib", "cv2", "dask", "distributed", "pyarrow", "pydantic")

_PROBE = """
import json, sys
from roughsense.cli import main, app
import typer.main
args = json.loads(sys.argv[1])
codes = [main(a) for a in (args or [["--help"]] + [[c, "--help"] for c in typer.main.get_command(app).commands])]
heavy = sorted({m.split(".")[0] for m in sys.modules} & set(json.loads(sys.argv[2])))
print(json.dumps({"codes": codes, "heavy": heavy}))
"""


@pytest.mark.parametrize("args", [[["--version"]], []], ids=["version", "every-help"])
def test_version_and_help_import_nothing_heavy(args):
    """The startup a user feels: --version, --help and COMMAND --help stay off the numerical stack."""
    run = subprocess.run([sys.executable, "-c", _PROBE, json.dumps(args), json.dumps(HEAVY)],
                         capture_output=True, text=True, timeout=120, env={**os.environ, "COLUMNS": "80"})
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout.strip().splitlines()[-1])
    assert set(result["codes"]) == {0}
    assert result["heavy"] == []


def test_defaults_imports_nothing_heavy():
    """roughsense.defaults is the one home of every default a user sees, imported by the CLI's options: it must not
    bring in the numerical stack, or every ``COMMAND --help`` would pay for it."""
    probe = "import json, sys, roughsense.defaults; print(json.dumps(sorted(m.split('.')[0] for m in sys.modules)))"
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert set(json.loads(run.stdout)) & set(HEAVY) == set()


def _default(command: str, name: str):
    return next(p.default for p in _commands()[command].params if p.name == name)


def test_every_option_default_is_its_homes_value():
    """The options show roughsense.defaults' values, and the layers use the same ones (one home, no copies)."""
    from roughsense import defaults
    from roughsense.io.sensor_settings import SensorSettings
    from roughsense.paper import PAPER_FORCES_N, PAPER_PARTICIPANTS, PAPER_REPETITIONS, PAPER_SESSIONS
    from roughsense.sim.config import SimulationConfig

    seeds = {name: _default(name, "seed") for name, c in _commands().items() if any(p.name == "seed" for p in c.params)}
    assert {"study", "fit", "features", "simulate", "protocol"} <= set(seeds)
    assert set(seeds.values()) == {defaults.SEED}
    assert _default("study", "permutations") == defaults.PERMUTATIONS == 199
    assert _default("study", "max_components") == defaults.MAX_COMPONENTS
    assert _default("study", "dpi") == _default("explore", "dpi") == defaults.DPI
    simulated = SimulationConfig()
    assert _default("simulate", "fingerprint_period_mm") == defaults.FINGERPRINT_PERIOD_MM == simulated.fingerprint_period_mm
    assert _default("simulate", "ridge_height_mm") == defaults.RIDGE_HEIGHT_MM == simulated.ridge_height_mm
    assert _default("simulate", "seed") == simulated.seed
    sensor = SensorSettings()
    assert (sensor.px_per_mm, sensor.roi, sensor.max_pixels) == (defaults.PX_PER_MM, defaults.ROI, defaults.MAX_PIXELS)
    assert _default("simulate", "repetitions") == _default("capture", "repetitions") == PAPER_REPETITIONS
    assert [float(f) for f in _default("simulate", "forces_n").split(",")] == list(PAPER_FORCES_N)
    assert (_default("protocol", "participants"), _default("protocol", "sessions")) == (PAPER_PARTICIPANTS, PAPER_SESSIONS)


def test_options_that_default_to_the_studys_value_name_the_fallback_in_their_help():
    """--px-per-mm, --roi and --max-pixels default to the study's; without a study the help's value applies."""
    from roughsense import defaults

    helps = {p.name: p.help for p in _commands()["features"].params}
    assert f"else {defaults.PX_PER_MM:g}" in helps["px_per_mm"]
    assert f"else {defaults.ROI}" in helps["roi"] and f"{defaults.CENTER_CROP_PX[0]}x" in helps["roi"]
    assert f"else {defaults.MAX_PIXELS}" in helps["max_pixels"]


def test_jobs_beyond_four_per_core_is_refused_before_any_work(run_cli, tmp_path):
    from roughsense._util.workers import MAX_JOBS_PER_CORE, usable_cores

    too_many = MAX_JOBS_PER_CORE * usable_cores() + 1
    code, _, err = run_cli("simulate", "--out", tmp_path / "s", "--jobs", str(too_many))
    line = _one_line_error(code, err)
    assert f"--jobs must be at most {too_many - 1}" in line
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize("args, option", [
    (["protocol", "--seed", "1", "--participants", "1_0"], "--participants"),
    (["protocol", "--seed", "١", "--out", "x.csv"], "--seed"),
    (["protocol", "--seed", "1", "--sessions", "inf"], "--sessions"),
    (["explore", "sweep.toml", "--out", "o", "--jobs", "2_0"], "--jobs"),
    (["capture", "--source", "x", "--out", "o", "--specimen", "R3", "--pad", "p", "--timeout-s", "nan"], "--timeout-s"),
    (["capture", "--source", "x", "--out", "o", "--specimen", "R3", "--pad", "p", "--discard", "2.5"], "--discard"),
])
def test_every_numeric_option_reads_numbers_as_a_csv_cell_is_read(run_cli, tmp_path, monkeypatch, args, option):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(*args)
    assert option in _one_line_error(code, err)
    assert list(tmp_path.iterdir()) == []


def test_a_library_warning_is_one_line_of_ours_without_source(run_cli, tmp_path, monkeypatch):
    """Any warning a library raises during a command (numpy here) is one ``roughsense: warning:`` line."""
    import roughsense.analysis.magnitude_estimation as analysis

    aggregate = analysis.aggregate_ratings

    def noisy(*args, **kwargs):
        np.log(np.zeros(1))  # RuntimeWarning: divide by zero encountered in log
        return aggregate(*args, **kwargs)

    monkeypatch.setattr(analysis, "aggregate_ratings", noisy)
    ratings = tmp_path / "ratings.csv"
    pd.DataFrame({"participant": ["P01", "P01"], "session": [1, 1], "specimen": ["R2", "R4"],
                  "rating": ["1.0", "0.5"]}).to_csv(ratings, index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        code, _, err = run_cli("ratings", ratings, "--out", tmp_path / "agg.csv")
    assert code == 0, err
    lines = [line for line in err.splitlines() if "RuntimeWarning" in line]
    assert lines == [line for line in lines if line.startswith("roughsense: warning: RuntimeWarning: divide by zero")]
    assert len(lines) == 1 and "np.log" not in err and f"{Path(__file__).name}:" in lines[0]


def test_cli_error_is_one_line_exit_2(run_cli, tmp_path):
    from roughsense.cli import app

    @app.command("_boom", hidden=True)
    def _boom() -> None:
        raise InputError("bad thing", path=tmp_path / "x.csv", row=2)

    code, out, err = run_cli("_boom")
    assert code == 2
    assert err.strip().count("\n") == 0 and "x.csv, row 2: bad thing" in err
    assert "Traceback" not in err
