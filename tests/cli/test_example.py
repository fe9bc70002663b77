"""``roughsense example``: the shipped examples come out of the installed package byte for byte, and nothing that
exists is replaced without --force (tests/test_package.py runs it from an installed wheel)."""
from __future__ import annotations

from pathlib import Path

import roughsense
from roughsense.cli.example import EXAMPLES

DATA = Path(roughsense.__file__).parent / "data"


def _tree(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_every_shipped_example_is_listed_and_every_listed_one_ships(run_cli):
    shipped = {p.name for p in (DATA / "examples").iterdir() if p.name not in ("README.md", "__pycache__")}
    assert shipped | {"samples"} == set(EXAMPLES)
    code, out, err = run_cli("example", "--list")
    assert code == 0 and err == ""
    assert [line.split()[0] for line in out.strip().splitlines()] == list(EXAMPLES)


def test_a_study_folder_is_copied_whole_and_refused_a_second_time_without_force(run_cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli("example", "my-study")
    assert code == 0, err
    copy = _tree(tmp_path / "my-study")
    assert copy == _tree(DATA / "examples" / "my-study") and len(copy) == 35  # 30 images, 4 files and its README
    assert "synthetic" in (tmp_path / "my-study" / "README.md").read_text()
    assert "my-study" in out
    code, _, err = run_cli("example", "my-study")
    assert code == 2 and err.strip().count("\n") == 0 and "already exists; pass --force" in err
    # --force restores what the user changed and keeps what the user added.
    (tmp_path / "my-study" / "study.toml").write_text("broken")
    (tmp_path / "my-study" / "notes.txt").write_text("mine")
    code, _, err = run_cli("example", "my-study", "--force")
    assert code == 0, err
    assert (tmp_path / "my-study" / "study.toml").read_bytes() == (DATA / "examples" / "my-study" / "study.toml").read_bytes()
    assert (tmp_path / "my-study" / "notes.txt").read_text() == "mine"


def test_a_file_example_goes_where_out_says_or_into_a_folder(run_cli, tmp_path):
    code, _, err = run_cli("example", "tiny.toml", "--out", tmp_path / "sweep.toml")
    assert code == 0, err
    assert (tmp_path / "sweep.toml").read_bytes() == (DATA / "examples" / "tiny.toml").read_bytes()
    code, _, err = run_cli("example", "paper_questions.toml", "--out", tmp_path)
    assert code == 0, err
    assert (tmp_path / "paper_questions.toml").read_bytes() == (DATA / "examples" / "paper_questions.toml").read_bytes()
    code, _, err = run_cli("example", "tiny.toml", "--out", tmp_path / "sweep.toml")
    assert code == 2 and "sweep.toml: already exists; pass --force" in err
    code, _, err = run_cli("example", "samples", "--out", tmp_path / "samples")
    assert code == 0, err
    assert _tree(tmp_path / "samples") == _tree(DATA / "samples")


def test_an_unknown_or_missing_name_is_one_line_naming_the_examples(run_cli, tmp_path):
    code, _, err = run_cli("example", "my_study", "--out", tmp_path / "x")
    assert code == 2 and err.strip().count("\n") == 0
    assert "no example named 'my_study'" in err and "my-study" in err and "--list" in err
    code, _, err = run_cli("example")
    assert code == 2 and "--list" in err and err.strip().count("\n") == 0
    assert not (tmp_path / "x").exists()
