"""Old option spellings, refused in one line naming the new name: nothing was released, so none is an alias.

One concept has one option name on every command (``--study``, ``--forces-n``, ``--jobs``). An older spelling is
declared by no command, so it never shows in ``--help``; typed, it is refused before the command line is parsed
(:func:`renamed_refusal`), exit 2, naming its new name. The table is the whole mechanism.

An option is said once (:func:`said_twice`): given twice, the command line is refused in one line naming both
spellings as typed -- the last one would otherwise win unsaid.
"""
from __future__ import annotations

#: ``{command: {old spelling: its one name}}``: refused, naming the new name.
RENAMED: dict[str, dict[str, str]] = {
    "study": {"--data": "--study"},
    "simulate": {"--forces": "--forces-n"},
    "capture": {"--forces": "--forces-n", "--force-input": "--forces-from"},
    "explore": {"--workers": "--jobs"},
}

#: Commands whose forces are ``--forces-n``: there, ``--force 2`` is a force typed as the overwrite flag.
FORCE_COMMANDS = ("simulate", "capture")


def command_index(args: list[str]) -> int | None:
    """Where the command's name is: the first word that is no option (roughsense's own options take no value)."""
    end = args.index("--") if "--" in args else len(args)
    return next((i for i in range(end) if not args[i].startswith("-")), None)


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


def _words(args: list[str]) -> tuple[int, list[str]] | None:
    """Where the command's name is and the words after it up to ``--`` (what may be its options)."""
    at = command_index(args)
    if at is None:
        return None
    end = args.index("--") if "--" in args else len(args)
    return at, args[at + 1:end]


def renamed_refusal(args: list[str]) -> str:
    """"COMMAND: --old is now --new" when a spelling of :data:`RENAMED` is typed after the command's name (as
    ``--old`` or ``--old=value``), else "". What follows ``--`` is an argument, never an option."""
    found = _words(args)
    table = RENAMED.get(args[found[0]], {}) if found else {}
    for word in found[1] if table else []:
        new = table.get(word.partition("=")[0])
        if new is not None:
            return f"{args[found[0]]}: {word.partition('=')[0]} is now {new}; see 'roughsense {args[found[0]]} --help'"
    return ""


def _takes(param) -> int:
    """How many words a click option takes after its name: 0 for a flag or a counter."""
    return 0 if getattr(param, "is_flag", False) or getattr(param, "count", False) else max(1, param.nargs)


def _option_words(command, words: list[str]) -> list[tuple[object, str]]:
    """``(click parameter, as typed)`` for each option of ``command`` in ``words``: ``--opt value``, ``--opt=value``,
    ``-o value``, ``-ovalue`` and grouped short flags (``-ab``). A word that is no option of the command (an
    argument, or a mistake click reports) is passed over; the value of an option is never read as an option."""
    params = {opt: p for p in command.params for opt in (*p.opts, *p.secondary_opts)}
    found, i = [], 0
    while i < len(words):
        word = words[i]
        name, sep, _ = word.partition("=")
        param = params.get(name)
        if param is not None:
            taken = 0 if sep else _takes(param)
            found.append((param, " ".join(words[i:i + 1 + taken])))
            i += 1 + taken
            continue
        if word.startswith("-") and not word.startswith("--") and len(word) > 2:  # -ovalue, or -ab
            for k in range(1, len(word)):
                param = params.get(f"-{word[k]}")
                if param is None:
                    break
                found.append((param, f"-{word[k]}" + (word[k + 1:] if _takes(param) else "")))
                if _takes(param):
                    break
        i += 1
    return found


def said_twice(args: list[str], commands: dict) -> str:
    """One line when an option of the command is given twice (under any of its spellings), else "".

    Options declared ``multiple`` (repeatable by design) may be given again."""
    found = _words(args)
    command = commands.get(args[found[0]]) if found else None
    if command is None:
        return ""
    name = args[found[0]]
    seen: dict[str, str] = {}
    for param, typed in _option_words(command, found[1]):
        if getattr(param, "multiple", False):
            continue
        if param.name in seen:
            one, first = max(param.opts, key=len), seen[param.name]
            what = (f"{one} is given twice ({first!r}, {typed!r})" if first == typed else
                    f"{first!r} and {typed!r} are the same option ({one})")
            return f"{name}: {what}; give it once; see 'roughsense {name} --help'"
        seen[param.name] = typed
    return ""
