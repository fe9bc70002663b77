"""``--images-XN`` for ``roughsense predict``: the images of one force, as many as follow the flag.

Click cannot give an option several values, so ``predict`` takes every token as an argument and this module splits
them by hand: bare images, and the images after each force's flag.
"""
from __future__ import annotations

from pathlib import Path

from ..errors import ConfigError

IMAGE_FLAG = "--images-"


def _slot_force(label: str) -> float | None:
    """The force of an ``--images-XN`` slot label, spelled as every number roughsense reads (io/numbers.py)."""
    from ..io.numbers import NumberError, parse_number

    if not label.endswith("N"):
        return None
    try:
        return float(parse_number(label[:-1], quantity="force_n"))
    except NumberError:
        return None


def split_image_flags(tokens: list[str]) -> tuple[list[Path], dict[str, list[Path]]]:
    """Bare images, and the images after each ``--images-XN`` flag (up to the next flag), by condition "XN".

    Any other unknown ``--option`` is refused rather than taken for a file.
    """
    positional: list[Path] = []
    by_condition: dict[str, list[Path]] = {}
    current: list[Path] | None = None
    for token in tokens:
        if token.startswith(IMAGE_FLAG):
            label, _, first = token[len(IMAGE_FLAG):].partition("=")
            condition = label.upper()
            force_n = _slot_force(condition)
            if force_n is None:
                raise ConfigError(f"{token.partition('=')[0]}: expected a force like --images-1n or --images-2.5n")
            condition = f"{force_n:g}N"
            current = by_condition.setdefault(condition, [])
            if first:
                current.append(Path(first))
        elif token.startswith("-") and len(token) > 1 and not Path(token).exists():
            raise ConfigError(f"no such option: {token}")
        elif current is not None:
            current.append(Path(token))
        else:
            positional.append(Path(token))
    return positional, by_condition
