"""Old option spellings (cli/_aliases.py) are refused in one line naming the new name, never show in --help, and
leave ``--`` alone."""
from __future__ import annotations

import re

import pytest
import typer.main

from roughsense.cli import _command, app
from roughsense.cli._aliases import RENAMED, force_hint, renamed_refusal, said_twice

#: Each old spelling with a command line that parses without running anything (the required options given), and a
#: value.
CASES = [
    ("simulate", "--forces", ["--out", "s"], "1.5,2.5"),
    ("capture", "--forces", ["--source", "0", "--out", "s", "--specimen", "R3", "--pad", "smooth"], "2,4"),
    ("capture", "--force-input", ["--source", "0", "--out", "s", "--specimen", "R3", "--pad", "smooth"], "f.csv"),
    ("explore", "--workers", ["sweep.toml", "--out", "o"], "3"),
    ("study", "--data", ["--out", "r"], "my-study"),
]


def _parsed(argv: list[str]) -> dict:
    """The parameters click hands the command's function."""
    command = _command().commands[argv[0]]
    with command.make_context(argv[0], argv[1:]) as ctx:
        return dict(ctx.params)


def test_the_table_holds_exactly_the_cases_tested():
    assert {(command, old) for command, table in RENAMED.items() for old in table} == {(c, o) for c, o, _, _ in CASES}


@pytest.mark.parametrize("command, old, required, value", CASES)
def test_an_old_spelling_is_refused_in_one_line_naming_its_new_name(run_cli, tmp_path, monkeypatch, command, old,
                                                                      required, value):
    """Nothing was released, so no old spelling is read as its new name: each is refused, exit 2, nothing made."""
    monkeypatch.chdir(tmp_path)
    new = RENAMED[command][old]
    for typed in ([old, value], [f"{old}={value}"]):
        code, out, err = run_cli(command, *required, *typed)
        lines = err.strip().splitlines()
        assert code == 2 and out == "" and len(lines) == 1, err
        assert lines[0] == f"roughsense: error: {command}: {old} is now {new}; see 'roughsense {command} --help'"
    assert list(tmp_path.iterdir()) == []
    by_new = _parsed([command, *required, new, value])  # the new name reads the value
    assert _parsed([command, *required]) != by_new
    parameter = next(p.name for p in _command().commands[command].params if new in p.opts)
    assert str(by_new[parameter]) == value


@pytest.mark.parametrize("name", [None, *typer.main.get_command(app).commands])
def test_no_old_spelling_shows_in_any_help(run_cli, name):
    code, out, _ = run_cli(*([] if name is None else [name]), "--help")
    assert code == 0
    for old in {old for table in RENAMED.values() for old in table}:
        assert re.search(rf"{re.escape(old)}(?![\w-])", out) is None, (name, old)


def test_no_command_declares_an_old_spelling():
    """Hidden by construction: the old spellings are no options of any command, so they cannot reach a signature."""
    declared = {opt for command in _command().commands.values() for p in command.params for opt in p.opts}
    assert declared & {old for table in RENAMED.values() for old in table} == set()
    assert {new for table in RENAMED.values() for new in table.values()} <= declared


def test_only_the_commands_words_before_a_double_dash_are_refused():
    assert renamed_refusal(["--debug", "explore", "s.toml", "--", "--workers", "--forces"]) == ""
    assert "--workers is now --jobs" in renamed_refusal(["--debug", "explore", "--workers", "2", "--", "x"])
    assert renamed_refusal(["fit", "--forces", "2"]) == ""  # no such old spelling on that command
    assert renamed_refusal(["simulate", "--forces-n", "2", "--force"]) == ""
    assert renamed_refusal(["--forces", "simulate"]) == ""  # before the command: roughsense's, not the command's
    assert renamed_refusal([]) == ""


def test_old_spellings_run_through_main(run_cli, tmp_path):
    """The whole path a user takes: refused before the value is read, so the line names the new option only."""
    code, _, err = run_cli("simulate", "--out", tmp_path / "s", "--forces", "2,x")
    assert code == 2 and "simulate: --forces is now --forces-n" in err and "not a number" not in err
    code, _, err = run_cli("explore", tmp_path / "absent.toml", "--out", tmp_path / "o", "--workers=0")
    assert code == 2 and "explore: --workers is now --jobs" in err and "absent.toml" not in err
    assert not (tmp_path / "s").exists() and not (tmp_path / "o").exists()


@pytest.mark.parametrize("args", [["simulate", "--out", "s", "--force", "2"], ["simulate", "--force=2,3"],
                                  ["capture", "--source", "0", "--out", "s", "--specimen", "R3", "--pad", "p",
                                   "--force", "1.5"]])
def test_a_force_typed_as_the_overwrite_flag_gets_a_hint(run_cli, tmp_path, monkeypatch, args):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(*args)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1
    assert "forces are --forces-n (e.g. --forces-n " in lines[0] and lines[0].endswith("--help'")
    assert list(tmp_path.iterdir()) == []


def test_no_hint_without_a_number_or_on_a_command_without_forces():
    assert force_hint(["simulate", "--force", "--out", "s"]) == ""
    assert force_hint(["explore", "x.toml", "--force", "2"]) == ""
    assert force_hint(["simulate", "--out", "s", "--", "--force", "2"]) == ""


def test_run_sweep_takes_n_jobs_only(tmp_path):
    """``workers=``, the Python keyword's old name, is no keyword at all: Python's own TypeError names it."""
    from roughsense.errors import ConfigError
    from roughsense.explore.runner import run_sweep

    with pytest.raises(ConfigError, match="--jobs must be from 1"):
        run_sweep(None, tmp_path / "out", n_jobs=100_000)
    with pytest.raises(TypeError, match="unexpected keyword argument 'workers'"):
        run_sweep(None, tmp_path / "out", workers=1)
    assert not (tmp_path / "out").exists()


#: An option said twice: under its old and new names, or the same spelling (long, ``=``, short, attached) twice.
TWICE = [
    (["study", "--study", "A", "--study=B"], "'--study A' and '--study=B'"),
    (["simulate", "--forces-n", "1", "--forces-n", "2,3", "--out", "s"], "'--forces-n 1' and '--forces-n 2,3'"),
    (["explore", "s.toml", "--out", "o", "--jobs", "2", "-j3"], "'--jobs 2' and '-j3'"),
    (["explore", "s.toml", "-j", "2", "--jobs=3", "--out", "o"], "'-j 2' and '--jobs=3'"),
    (["simulate", "--seed", "1", "--seed=2", "--out", "s"], "'--seed 1' and '--seed=2'"),
    (["simulate", "-o", "s", "--out", "t"], "'-o s' and '--out t'"),
    (["predict", "m.json", "-ob.csv", "--out", "a.csv"], "'-ob.csv' and '--out a.csv'"),
    (["study", "--seed", "-1", "--seed", "2"], "'--seed -1' and '--seed 2'"),
    (["simulate", "--out", "s", "--force", "--force"], "--force is given twice"),
]


@pytest.mark.parametrize("argv, named", TWICE)
def test_an_option_said_twice_is_refused_naming_both_spellings(run_cli, tmp_path, monkeypatch, argv, named):
    """D9: the last one won unsaid (``study --data A --study B`` analysed B)."""
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(*argv)
    lines = err.strip().splitlines()
    assert code == 2 and out == "" and len(lines) == 1, err
    assert named in lines[0] and "give it once" in lines[0] and f"roughsense {argv[0]} --help" in lines[0]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv", [
    ["simulate", "--out", "s", "--seed", "--seed"],  # one --seed whose value is the word "--seed" (click's reading)
    ["study", "--out", "r", "--", "--out", "x"],  # after --, words are arguments
    ["simulate", "--out", "s", "--forces-n", "1", "--seed", "3"],
    ["explore", "-j", "2", "--out", "--jobs"],
])
def test_an_option_said_once_passes(argv):
    assert said_twice(argv, _command().commands) == ""


def test_a_repeatable_option_may_be_given_again():
    import click

    command = click.Command("c", params=[click.Option(["--tag", "-t"], multiple=True), click.Option(["--seed"])])
    assert said_twice(["c", "--tag", "a", "-t", "b"], {"c": command}) == ""
    assert "--seed" in said_twice(["c", "--seed", "1", "--tag", "a", "--seed", "2"], {"c": command})


#: An option said under its old and its new name: the old spelling is refused first, naming the new one.
OLD_AND_NEW = [
    (["study", "--data", "A", "--study", "B"], "study: --data is now --study"),
    (["study", "--study=B", "--data=A"], "study: --data is now --study"),
    (["simulate", "--forces", "1", "--forces-n", "2,3", "--out", "s"], "simulate: --forces is now --forces-n"),
    (["explore", "s.toml", "--out", "o", "--workers", "2", "-j3"], "explore: --workers is now --jobs"),
]


@pytest.mark.parametrize("argv, named", OLD_AND_NEW)
def test_an_option_said_by_its_old_and_new_names_is_refused_for_the_old(run_cli, tmp_path, monkeypatch, argv, named):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(*argv)
    lines = err.strip().splitlines()
    assert code == 2 and out == "" and len(lines) == 1 and named in lines[0], err
    assert list(tmp_path.iterdir()) == []


def test_a_message_names_the_option_as_declared(run_cli, tmp_path):
    """No spelling is rewritten any more, so an error about an option names it as the command declares it."""
    code, _, err = run_cli("explore", tmp_path / "absent.toml", "--out", tmp_path / "o", "--jobs=0")
    assert code == 2 and "--jobs must be from 1" in err and "--workers" not in err


@pytest.mark.parametrize("command, old", [(c, o) for c, table in RENAMED.items() for o in table])
def test_a_spelling_renamed_before_release_is_refused_naming_its_new_name(run_cli, tmp_path, monkeypatch, command,
                                                                           old):
    monkeypatch.chdir(tmp_path)
    new = RENAMED[command][old]
    code, _, err = run_cli(command, f"{old}=x", "--out", "o")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert f"{old} is now {new}" in err
    declared = {opt for p in _command().commands[command].params for opt in p.opts}
    assert new in declared and old not in declared
    assert list(tmp_path.iterdir()) == []


def test_every_command_that_writes_one_output_takes_dash_o():
    """``-o`` is ``--out`` on every command with an ``--out`` (study, simulate, explore and capture lacked it)."""
    outs = {name: p for name, c in _command().commands.items() for p in c.params if "--out" in p.opts}
    assert {"study", "simulate", "explore", "capture", "fit", "predict", "features"} <= set(outs)
    assert {name for name, out in outs.items() if "-o" not in out.opts} == set()
