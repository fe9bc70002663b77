"""``roughsense example``: copy a shipped example (a study folder, a sweep file, the sample images) out of the package.

The examples live in the installed package (``roughsense/data``), not in a checkout, so the tutorial works from a
wheel as from a clone. They are read through importlib.resources, which finds them however the package was installed.
"""
from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import PASS_FORCE, ConfigError, OutputExistsError

ORDER = 95

#: Each shipped example: where it lives in the package, and one line on what it is.
EXAMPLES: dict[str, tuple[str, str]] = {
    "my-study": ("data/examples/my-study", "a complete tiny study folder (30 synthetic images, ratings): `study --study`"),
    "tiny.toml": ("data/examples/tiny.toml", "a sweep of the twin small enough for about a minute: `explore`"),
    "paper_questions.toml": ("data/examples/paper_questions.toml",
                             "the sweep asking the twin the paper's open questions: `explore`"),
    "samples": ("data/samples", "five synthetic contact images, one per image format: `features --roi auto`"),
}


def _resource(name: str):
    """The example's Traversable in the installed package; an unknown name is one line listing the known ones."""
    from importlib.resources import files

    if name not in EXAMPLES:
        raise ConfigError(f"no example named {name!r}; the examples are {', '.join(EXAMPLES)} (roughsense example --list)")
    node = files("roughsense")
    for part in EXAMPLES[name][0].split("/"):
        node = node / part
    return node


def _files(node, prefix: Path = Path()) -> list[tuple[Path, bytes]]:
    """Every file under a Traversable folder, with its path relative to it (folders of caches left out)."""
    found = []
    for child in sorted(node.iterdir(), key=lambda c: c.name):
        if child.name == "__pycache__":
            continue
        if child.is_dir():
            found += _files(child, prefix / child.name)
        else:
            found.append((prefix / child.name, child.read_bytes()))
    return found


def _copy_folder(node, out: Path, force: bool) -> int:
    """Swap in a whole copy (a killed run leaves the earlier folder); with --force the user's own files are kept."""
    from .._util.atomic import staged_folder
    from .._util.lock import output_lock
    from ..io.writer import refuse_captured

    with output_lock(out, command="example"):
        if out.exists() and not force:
            raise OutputExistsError(f"already exists; {PASS_FORCE} to replace it", path=out)
        refuse_captured(out, "an example is not copied over captured frames; choose a new folder")
        content = _files(node)
        ours = {str(rel) for rel, _ in content} | {str(parent) for rel, _ in content for parent in rel.parents}
        with staged_folder(out, owned=lambda rel: str(rel) in ours) as folder:
            for rel, data in content:
                (folder / rel).parent.mkdir(parents=True, exist_ok=True)
                (folder / rel).write_bytes(data)
    return len(content)


def example(
    name: Annotated[str | None, typer.Argument(
        metavar="NAME", show_default=False, help="The example to copy (see --list).")] = None,
    out: Annotated[Path | None, typer.Option(
        "--out", "-o", show_default=False,
        help="Where the copy goes (default: NAME in the current folder); a file example given a folder goes into it.")
    ] = None,
    list_: Annotated[bool, typer.Option("--list", help="List the shipped examples and exit.")] = False,
    force: Annotated[bool, typer.Option("--force", help="Replace an existing copy (files you added to a folder are "
                                                       "kept).")] = False,
) -> None:
    """Copy a shipped example out of the installed package, to run or to edit as the start of your own.

    `roughsense example my-study` writes ./my-study, a study folder to lay your own images and ratings out like;
    `roughsense example tiny.toml` a sweep file for `roughsense explore`. Nothing that exists is replaced without
    --force.
    """
    from .._util.atomic import check_can_write, write_bytes

    if list_ or name is None:
        if name is None and not list_:
            raise ConfigError("name an example to copy, or pass --list to see them")
        width = max(map(len, EXAMPLES))
        for known, (_, what) in EXAMPLES.items():
            print(f"{known:<{width}}  {what}")
        return
    node = _resource(name)
    target = Path(name) if out is None else out
    if node.is_dir():
        count = _copy_folder(node, target, force)
        print(f"wrote {target}/ ({count} files)")
        return
    if target.is_dir():
        target = target / name
    check_can_write(target, force=force)
    write_bytes(target, node.read_bytes())
    print(f"wrote {target}")


def register(app: typer.Typer) -> None:
    app.command("example")(example)
