"""study.toml's reader (io/study_config.py): it accepts only what the writers of study.toml can write back."""
from __future__ import annotations

import shutil

import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from roughsense.errors import InputError
from roughsense.io.study import read_study
from roughsense.io.study_config import MAX_CONFIG_DEPTH, nesting_depth, read_config
from tests.fuzzing import EXAMPLES, FUZZ


def nested(depth: int) -> str:
    """A [simulation] key holding arrays ``depth`` deep (any key is allowed in that table)."""
    return "\n[simulation]\nx = " + "[" * depth + "1" + "]" * depth + "\n"


def test_nesting_depth_counts_tables_and_arrays():
    assert nesting_depth(1) == 0 and nesting_depth({}) == 1 and nesting_depth({"a": [[1]]}) == 3
    assert nesting_depth({"pads": {"fingerprint": {"ridge_period_mm": 1.0}}}) == 3
    assert nesting_depth([[[[]]]] * 2) == 4


@pytest.mark.parametrize("depth", [150, 300, 450])
def test_a_study_toml_nested_deeper_than_any_writer_writes_is_refused(tmp_path, depth):
    """On 390ce82 these parsed (tomllib reads ~1000 levels) while calibrate's tomlkit refuses past 100 levels."""
    import tomlkit

    path = tmp_path / "study.toml"
    path.write_text("[study]\nname = 's'\n" + nested(depth))
    with pytest.raises(tomlkit.exceptions.ParseError):  # what calibrate would meet writing px_per_mm back
        tomlkit.parse(path.read_text())
    with pytest.raises(InputError, match=r"study\.toml: is not a study\.toml: its values are nested too deeply "
                                         rf"\({depth + 2} levels, at most {MAX_CONFIG_DEPTH}"):
        read_config(path)


def test_a_study_toml_at_the_depth_limit_reads(tmp_path):
    path = tmp_path / "study.toml"
    path.write_text("[study]\nname = 's'\n" + nested(MAX_CONFIG_DEPTH - 2))
    assert nesting_depth(read_config(path)) == MAX_CONFIG_DEPTH


def test_check_refuses_a_deeply_nested_study_toml_in_one_line(run_cli, simulated_tiny, tmp_path):
    study = tmp_path / "study"
    shutil.copytree(simulated_tiny, study)
    with (study / "study.toml").open("a") as handle:
        handle.write("\n[simulation.deep]\nx = " + "[" * 200 + "1" + "]" * 200 + "\n")
    code, out, err = run_cli("check", study)
    text = out + err
    assert code == 2 and "Traceback" not in text
    lines = [line for line in text.splitlines() if "nested too deeply" in line]
    assert len(lines) == 1 and "study.toml" in lines[0]


def test_a_multiline_string_does_not_hide_a_toml_spelling(tiny_copy):
    """28.5: after a multi-line string holding \\\""" the old pattern lost track: px_per_mm = 3_49 read as 349."""
    toml = tiny_copy / "study.toml"
    text = toml.read_text()
    assert "px_per_mm = 20.0" in text
    toml.write_text(text.replace("[study]\n", '[study]\nnote = """a \\""" px_per_mm = 1 """\n')
                    .replace("px_per_mm = 20.0", "px_per_mm = 2_0") + '# a comment quoting """\n')
    with pytest.raises(InputError, match=r"line \d+: '2_0' is not a number as roughsense reads one \(no '_' between digits"):
        read_study(tiny_copy)


def test_valid_toml_with_number_like_text_is_accepted(tiny_copy):
    """28.5: ``1_000`` inside a string and a key named ``inf`` were refused as numbers."""
    toml = tiny_copy / "study.toml"
    text = toml.read_text()
    toml.write_text(text.replace('name = "tiny"', "name = \"batch 1_000 0x10 inf\"\n# a comment 1_0\ninf = 1.0")
                    + "\n[pads.inf]\nridge_period_mm = 1.5\n[pads.'1_000']\nridge_period_mm = 2e0\n")
    with pytest.warns(Warning, match="unknown key 'inf' in \\[study\\] ignored"):  # a warning, not a refusal
        study_ = read_study(tiny_copy)
    assert study_.name == "batch 1_000 0x10 inf" and study_.pad_ridge_period_mm == {"inf": 1.5, "1_000": 2.0}


TOML_NUMBERS = ["1", "-2", "+3", "1.5", "1e3", "0.5", "2E-1", "1_000", "0x10", "0o7", "0b1", "inf", "-inf", "nan",
                "+nan", "1_0.5", "1e1_0"]


TOML_TEXT = st.text(alphabet=st.sampled_from(list("ax1_0 ='\"\\\n#[]inf")), max_size=12)


def _foreign(spelling: str) -> bool:
    bare = spelling.lstrip("+-")
    return "_" in bare or bare[:2] in ("0x", "0o", "0b") or bare in ("inf", "nan")


@st.composite
def toml_strings(draw) -> str:
    """A TOML string of any of the four kinds holding ``TOML_TEXT``; quotes escaped at random where allowed."""
    text = draw(TOML_TEXT)
    kind = draw(st.sampled_from(["basic", "multi", "literal", "multi_literal"]))
    if kind == "literal" and "'" not in text and "\n" not in text:
        return f"'{text}'"
    if kind == "multi_literal" and "\'\'\'" not in text and not text.endswith("'"):
        return f"\'\'\'{text}\'\'\'"
    out, run = [], 0
    for ch in text:
        if ch == "\\":
            out.append("\\\\")
            run = 0
        elif ch == '"' and kind == "multi" and run < 2 and not draw(st.booleans()):
            out.append('"')  # up to two unescaped quotes inside a multi-line string
            run += 1
        elif ch == '"':
            out.append('\\"')
            run = 0
        elif ch == "\n" and kind != "multi":
            out.append("\\n")
            run = 0
        else:
            out.append(ch)
            run = 0
    body = "".join(out)
    if kind == "multi":
        return '"""' + body + ('\\"' if body.endswith('"') else "") + '"""'
    return f'"{body}"'


@pytest.mark.slow
@settings(FUZZ, max_examples=max(300, EXAMPLES * 4))
@given(data=st.data())
def test_the_toml_spelling_check_sees_values_only(data):
    """A TOML number is refused iff it is spelled as no CSV cell may be; strings, keys and comments never are."""
    import tomllib

    from roughsense.io.numbers import toml_spelling_problem

    lines, spellings = ["[t]"], []
    for k in range(data.draw(st.integers(1, 5))):
        key = data.draw(st.sampled_from(["a", "inf", "nan", "1_000", "0x10", f"k{k}", '"q.1_0"', "'x = 0x1'"]))
        values = data.draw(st.lists(st.one_of(st.sampled_from(TOML_NUMBERS), toml_strings()), min_size=1, max_size=3))
        spellings += [v for v in values if v in TOML_NUMBERS]
        value = values[0] if len(values) == 1 else "[" + ", ".join(values) + "]"
        comment = data.draw(st.sampled_from(["", " # 1_0 0x2", " #"]))
        lines.append(f"{key}{k} = {value}{comment}" if not key.startswith(("'", '"')) else f"{key[:-1]}{k}{key[-1]} = {value}")
    text = "\n".join(lines) + "\n"
    try:
        tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        event("not TOML")
        return
    problem = toml_spelling_problem(text)
    foreign = [s for s in spellings if _foreign(s)]
    assert (problem is not None) == bool(foreign), (text, problem)
    if problem is not None:
        assert any(repr(s) in problem for s in foreign), (text, problem)
