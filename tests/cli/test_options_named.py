"""Every option a message of roughsense suggests exists (issue 44: a 20000 x 20000 image was refused with advice to
pass ``--max-pixels``, which ``predict`` does not have).

Each string literal in the package's source (f-strings' text parts too) is searched for ``--option`` words; each
must be an option of some command, and the advice said after an image above the pixel limit names only options of
the command that says it."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import numpy as np
import pytest

import roughsense
from roughsense.cli import _command
from roughsense.cli._aliases import RENAMED
from roughsense.cli._common import PIXEL_LIMIT_ADVICE

SRC = Path(roughsense.__file__).parent
OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9]*(?:-[a-z0-9]+)*")
#: Roughsense's own options that no command declares: the program's, and click's help.
GLOBAL = {"--debug", "--version", "--help"}


def _declared() -> dict[str, set[str]]:
    commands = _command().commands
    return {name: {o for p in c.params for o in (*p.opts, *p.secondary_opts)} for name, c in commands.items()}


#: predict's force slots (cli/image_flags.py): options click never sees, split from its arguments by hand.
IMAGE_SLOTS = re.compile(r"--images(-[0-9.]*n?)?")


def _literals(path: Path):
    """Every string literal but docstrings (they describe the code, and may spell an option's placeholder)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                  and node.body and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            yield node.lineno, node.value


def _suggested() -> list[tuple[str, int, str]]:
    found = []
    for path in sorted(SRC.rglob("*.py")):
        for line, text in _literals(path):
            found.extend((f"{path.relative_to(SRC)}:{line}", line, option) for option in OPTION.findall(text))
    return found


def test_the_search_finds_the_suggestions_it_is_about():
    options = {option for _, _, option in _suggested()}
    assert {"--max-pixels", "--study", "--force", "--jobs", "--out"} <= options


def test_every_option_a_message_names_is_an_option_of_some_command():
    declared = set().union(*_declared().values()) | GLOBAL
    old = {o for table in RENAMED.values() for o in table}  # named to refuse them
    unknown = sorted({(where, option) for where, _, option in _suggested()
                      if option not in declared | old and not IMAGE_SLOTS.fullmatch(option)})
    assert unknown == []


@pytest.mark.parametrize("command", sorted(PIXEL_LIMIT_ADVICE))
def test_the_pixel_limit_advice_names_only_the_commands_own_options(command):
    assert set(OPTION.findall(PIXEL_LIMIT_ADVICE[command])) <= _declared()[command]


def test_a_huge_image_is_advised_only_what_the_command_has():
    """The refusal itself names no option; the command's advice is chosen in one place (cli/_common.limit_advice),
    which cli/__init__.py adds to the line."""
    from roughsense.cli._common import limit_advice
    from roughsense.io.images import PixelLimitError, check_pixels

    header = _png_header(20000, 20000)
    with pytest.raises(PixelLimitError) as raised:
        check_pixels(header, 10**8, "huge.png")
    assert "--" not in str(raised.value)
    assert limit_advice(raised.value, "predict") == ""
    assert "--max-pixels" in limit_advice(raised.value, "features")
    assert "--max-pixels" not in limit_advice(raised.value, "study")


def _png_header(width: int, height: int) -> np.ndarray:
    import struct
    import zlib

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    chunk = struct.pack(">I", len(ihdr)) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
    return np.frombuffer(b"\x89PNG\r\n\x1a\n" + chunk, np.uint8)
