"""Old option spellings, kept for one release: each is rewritten to its one name before the command line is parsed.

One concept has one option name on every command (``--study``, ``--forces-n``, ``--jobs``); an older spelling still
works, but no command declares it, so it never shows in ``--help`` and adds nothing to a command's signature. The
table is the whole mechanism: CHANGELOG.md lists the same pairs.
"""
from __future__ import annotations

#: ``{command: {old spelling: one name}}``.
ALIASES: dict[str, dict[str, str]] = {
    "study": {"--data": "--study"},
    "simulate": {"--forces": "--forces-n"},
    "capture": {"--forces": "--forces-n"},
    "explore": {"--workers": "--jobs"},
}

#: Commands whose forces are ``--forces-n``: there, ``--force 2`` is a force typed as the overwrite flag.
FORCE_COMMANDS = ("simulate", "capture")


def command_index(args: list[str]) -> int | None:
    """Where the command's name is: the first word that is no option (roughsense's own options take no value)."""
    end = args.index("--") if "--" in args else len(args)
    return next((i for i in range(end) if not args[i].startswith("-")), None)


def _spelled(token: str, table: dict[str, str]) -> str:
    name, sep, value = token.partition("=")
    new = table.get(name)
    return token if new is None else f"{new}{sep}{value}"


def apply_aliases(args: list[str]) -> list[str]:
    """``args`` with every old spelling after the command's name (``--opt`` and ``--opt=value``) replaced by its one
    name; what follows ``--`` is an argument, never an option, and stays as typed."""
    at = command_index(args)
    table = ALIASES.get(args[at]) if at is not None else None
    if not table:
        return list(args)
    end = args.index("--") if "--" in args else len(args)
    return [*args[:at + 1], *(_spelled(a, table) for a in args[at + 1:end]), *args[end:]]


def force_hint(args: list[str]) -> str:
    """"; forces are --forces-n" when ``--force`` is followed by a number on a command that presses (``simulate
    --force 2``), else "": the overwrite flag takes no value, so click's own error would not say what was meant."""
    at = command_index(args)
    if at is None or args[at] not in FORCE_COMMANDS:
        return ""
    end = args.index("--") if "--" in args else len(args)
    words = args[at + 1:end]
    for i, word in enumerate(words):
        name, sep, value = word.partition("=")
        given = value if sep else (words[i + 1] if i + 1 < len(words) else "")
        if name == "--force" and _is_number(given.split(",")[0]):
            return f"; forces are --forces-n (e.g. --forces-n {given})"
    return ""


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
