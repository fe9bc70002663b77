"""The ``roughsense`` command: a thin typer app that parses options, calls the layers and maps errors to exit codes.

Each command lives in its own module in this package and exposes ``register(app)``; modules are
discovered here so that adding a command never edits a shared file. This module owns the one
place where errors become exit codes: a :class:`RoughsenseError` (or an OS error about a user's
file) is one line on stderr and exit 2; a traceback only with ``--debug``.
"""
from __future__ import annotations

import importlib
import os
import pkgutil
import sys
import traceback
import warnings

import typer

from .._util import interrupt
from ..errors import RoughsenseError, one_line
from ._aliases import command_index, force_hint, renamed_refusal, said_twice
from ._common import close_line, limit_advice

app = typer.Typer(
    name="roughsense",
    help=(
        "Estimate perceived macroscopic roughness from contact images of a compliant pad "
        "(Yanwari & Okamoto, Sensors 2025): features, PLS models, perception data, simulation, the study and the rig."
    ),
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode="markdown",
)

_state = {"debug": bool(os.environ.get("ROUGHSENSE_DEBUG"))}
_python_showwarning = warnings.showwarning
#: Modules whose warnings a run ignores: Pillow's header reads (io/images.py, in decode threads) warn about sizes and
#: metadata that roughsense checks and reports in its own words.
PILLOW_WARNINGS = r"PIL(\.|$)"


def _show_version(value: bool) -> None:
    if value:
        from .. import __version__

        typer.echo(f"roughsense {__version__}")
        raise typer.Exit()


@app.callback()
def _global_options(
    debug: bool = typer.Option(False, "--debug", help="Show full tracebacks instead of one-line errors (before or "
                               "after the command)."),
    version: bool = typer.Option(False, "--version", callback=_show_version, is_eager=True,
                                 help="Print the version and exit."),
) -> None:
    if debug:
        _state["debug"] = True


def _register_commands() -> None:
    modules = sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))
    registered = []
    for name in modules:
        module = importlib.import_module(f"{__name__}.{name}")
        register = getattr(module, "register", None)
        if register is not None:
            registered.append((getattr(module, "ORDER", 100), name, register))
    for _, _, register in sorted(registered):
        register(app)


_register_commands()


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Every warning is one line like the errors: roughsense's own as they are, a library's (numpy, pandas ...)
    with its kind and origin but no source line. ``--debug`` keeps Python's format for a library's warning."""
    from ..errors import RoughsenseWarning

    close_line()
    if issubclass(category, RoughsenseWarning):
        print(f"roughsense: warning: {one_line(message)}", file=sys.stderr)
    elif _state["debug"]:
        _python_showwarning(message, category, filename, lineno, file, line)
    else:
        origin = f"{os.path.basename(str(filename))}:{lineno}"
        print(f"roughsense: warning: {one_line(f'{category.__name__}: {message} ({origin})')}", file=sys.stderr)


def _fail(message: str) -> int:
    close_line()
    print(f"roughsense: error: {one_line(message)}", file=sys.stderr)
    return 2


def _said_once(args: list[str], group) -> str:
    """One line when the command line says an option by its old spelling or twice, else ""."""
    return renamed_refusal(args) or said_twice(args, getattr(group, "commands", {}))


def _take_debug(args: list[str]) -> tuple[list[str], bool]:
    """``--debug`` is roughsense's, not a command's: take it from anywhere before a ``--``, so
    ``roughsense study --debug`` works like ``roughsense --debug study``."""
    end = args.index("--") if "--" in args else len(args)
    kept = [a for a in args[:end] if a != "--debug"] + args[end:]
    return kept, len(kept) < len(args)


def _command():
    """The click group typer builds, with two touches to every command's options.

    A flag shows no ``<bool>`` type in the help (it takes no value), and ``--help`` defaults to False rather
    than None: typer validates a None through pydantic, which would cost every ``COMMAND --help`` 0.1 s.
    """
    group = typer.main.get_command(app)
    for command in (group, *getattr(group, "commands", {}).values()):
        for param in (*command.params, command.get_help_option(typer.Context(command))):
            if param is not None and getattr(param, "is_flag", False):
                param.metavar = ""
                if param.default is None:
                    param.default = False
    return group


def _usage_error(exc: Exception, args: list[str]) -> int:
    """click's usage error as the project's one line: what is wrong, naming the option, and where the help is."""
    close_line()
    if isinstance(exc, typer.Abort):  # end of input at a prompt
        print("roughsense: aborted", file=sys.stderr)
        return 1
    if type(exc).__name__ == "NoArgsIsHelpError":  # bare ``roughsense``: the help (rich has printed it already)
        if exc.format_message().strip():
            typer.echo(exc.format_message())
        return 2
    ctx = getattr(exc, "ctx", None)
    if ctx is not None:
        path = ctx.command_path
    else:  # an option without its value: click's parser knows no command, the arguments do
        name = next((a for a in args if not a.startswith("-")), "")
        path = f"roughsense {name}" if name in typer.main.get_command(app).commands else "roughsense"
    message = exc.format_message().strip().rstrip(".")
    where = path.removeprefix("roughsense").strip()
    hint = force_hint(args)
    return _fail(f"{where + ': ' if where else ''}{message[:1].lower()}{message[1:]}{hint}; see '{path} --help'")


def main(argv: list[str] | None = None) -> int:
    """Run the CLI and return its exit code (tests call this directly).

    click's usage errors (a bad option, a missing argument) and everything the library raises surface here and
    are turned into one line; ``--help`` and ``--version`` return 0. An option's old spelling is refused naming its
    new name, and an option is said once (cli/_aliases.py).
    """
    args, debug = _take_debug(list(sys.argv[1:] if argv is None else argv))
    if debug:
        _state["debug"] = True
    group = _command()
    refusal = _said_once(args, group)
    if refusal:
        _state["debug"] = bool(os.environ.get("ROUGHSENSE_DEBUG"))
        return _fail(refusal)
    warnings.showwarning = _show_warning
    try:
        with warnings.catch_warnings():  # the main thread, around the whole run: workers never touch the filters
            warnings.filterwarnings("ignore", module=PILLOW_WARNINGS)
            code = group.main(args=args, prog_name="roughsense", standalone_mode=False)
        interrupt.check()  # stopped after its last safe point: still a run that was stopped, not a success
        return code if isinstance(code, int) and not isinstance(code, bool) else 0
    except SystemExit as exc:
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else _fail(str(code)))
    except KeyboardInterrupt:  # interrupt.Interrupted at a safe point, or a second Ctrl-C
        close_line()
        print("roughsense: interrupted", file=sys.stderr)
        return interrupt.exit_code()
    except typer.TyperException as exc:  # click's usage errors, and Abort (an end of input at a prompt)
        return _usage_error(exc, args)
    except RoughsenseError as exc:
        close_line()
        if _state["debug"]:
            traceback.print_exc()
        at = command_index(args)
        return _fail(str(exc) + limit_advice(exc, None if at is None else args[at]))
    except OSError as exc:
        close_line()
        if _state["debug"]:
            traceback.print_exc()
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        return _fail(f"{where}{exc.strerror or exc}")
    except Exception as exc:  # a bug: still one line, but say how to get the traceback
        close_line()
        if _state["debug"]:
            traceback.print_exc()
            return 1
        print(f"roughsense: internal error: {type(exc).__name__}: {one_line(exc)} (rerun with --debug for details)",
              file=sys.stderr)
        return 1
    finally:
        _state["debug"] = bool(os.environ.get("ROUGHSENSE_DEBUG"))
        _state["typed"] = {}
        warnings.showwarning = _python_showwarning


def run() -> None:
    """Console-script entry point. ``kill`` (SIGTERM) stops a run as Ctrl-C does, at its next safe point
    (``_util/interrupt.py``): nothing is committed after it, its lock and half-built output go, one line says
    "interrupted" and the exit code is 143 (130 for Ctrl-C). A run started in the background (``&``, nohup, a
    script) ignores Ctrl-C's SIGINT, so SIGTERM is the signal that reaches it."""
    interrupt.install()
    sys.exit(main())
