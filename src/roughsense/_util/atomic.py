"""Atomic writes: a failed or killed run must never leave a partial file or a mixed folder behind.

A file is written to a temporary sibling and renamed over the target with :func:`os.replace`, which is
atomic on POSIX within one file system. A folder whose files only make sense together (a simulated study,
a report) is built as a sibling folder and swapped in whole: :class:`FolderSwap` / :func:`staged_folder`.
"""
from __future__ import annotations

import contextlib
import glob
import os
import re
import secrets
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO

from ..errors import PASS_FORCE, ConfigError, OutputExistsError, RoughsenseError
from . import interrupt
from .files import foreign_reason
from .text import spreadsheet_safe


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask


def _default_file_mode() -> int:
    """The mode ``open()`` would give a new file (0666 minus the umask); mkstemp alone gives 0600."""
    return 0o666 & ~_umask()


def check_can_write(path: str | os.PathLike[str], *, force: bool = False,
                    inputs: Iterable[str | os.PathLike[str]] = (), option: str = "--out") -> Path:
    """Refuse to replace an existing file unless ``force``, and one of the run's ``inputs`` even with it
    (:func:`refuse_inputs`): user data is never overwritten silently."""
    target = Path(path)
    refuse_inputs(target, inputs, option=option)
    if target.exists() and not force:
        raise OutputExistsError(f"already exists; {PASS_FORCE} to replace it", path=target)
    if target.exists() and target.is_dir():
        raise OutputExistsError("is a folder, expected a file path", path=target)
    return target


def _resolved(path: Path) -> Path:
    try:
        return path.resolve()
    except (OSError, RuntimeError):  # a symlink loop: compare the path as written
        return path.absolute()


def refuse_inputs(path: str | os.PathLike[str], inputs: Iterable[str | os.PathLike[str]], *,
                  option: str = "--out") -> None:
    """Refuse an output that is an input of the same run, --force or not: the run would replace what it reads.

    An output is an input when it resolves to it (through symbolic links, or as a hard link of it), lies inside an
    input folder (a study's images/), or is a folder holding an input (a report written over its study).
    """
    target = _resolved(Path(path))
    for item in inputs:
        source = _resolved(Path(item))
        inside = source.is_dir() and target.is_relative_to(source)
        if target == source or inside or source.is_relative_to(target) or _same_file(Path(path), Path(item)):
            what = "inside the input folder" if inside and target != source else "an input of this run"
            raise ConfigError(f"{option} {path} is {what} {item}; choose another path (--force does not change this: "
                              "the run would overwrite what it reads)")


def check_outputs(outputs: dict[str, str | os.PathLike[str] | None], *, force: bool = False,
                  inputs: Iterable[str | os.PathLike[str]] = ()) -> None:
    """Check every file a run writes (``{option: path}``; None: not asked for) before any work: none is an input
    (whatever ``force`` says), no two are the same file, and none exists unless ``force``."""
    inputs = list(inputs)
    given = [(option, Path(path)) for option, path in outputs.items() if path is not None]
    for i, (option, path) in enumerate(given):
        for other, earlier in given[:i]:
            if _resolved(path) == _resolved(earlier) or _same_file(path, earlier):
                raise ConfigError(f"{option} {path} is also {other}: the run would write one over the other; "
                                  "choose another path")
        check_can_write(path, force=force, inputs=inputs, option=option)


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "w", *, file_mode: int | None = None, **kwargs) -> Iterator[IO]:
    """Open a temporary sibling of ``path``; on clean exit fsync and rename it into place. ``file_mode``: the
    permissions the file gets (a file rewritten in place keeps its own), else the umask's."""
    if mode not in ("w", "wb"):
        raise ValueError("atomic_open only writes whole files ('w' or 'wb')")
    target = Path(path)
    parent = target.parent if str(target.parent) else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        _remove_dead_temporaries(parent, target.name)
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.{os.getpid()}.", suffix=".tmp", dir=parent)
    except OSError as exc:
        raise RoughsenseError(f"cannot write: {exc.strerror or exc}", path=target) from exc
    tmp = Path(tmp_name)
    try:
        os.chmod(tmp, _default_file_mode() if file_mode is None else file_mode)
        if "b" in mode:
            handle = os.fdopen(fd, mode)
        else:
            kwargs.setdefault("encoding", "utf-8")
            kwargs.setdefault("newline", "")
            handle = os.fdopen(fd, mode, **kwargs)
        with handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        interrupt.check()  # a run asked to stop commits nothing more
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) and _about_the_write(exc, tmp):  # name the file asked for, never the temporary
            raise RoughsenseError(f"cannot write: {exc.strerror or exc}", path=target) from exc
        raise


def _about_the_write(exc: OSError, tmp: Path) -> bool:
    """An error of the write itself (a full disk: no file named) or of its temporary or rename (a sticky shared
    folder refuses the rename, naming the temporary), not one of other files the caller's block touched."""
    names = {None, str(tmp), os.fsencode(tmp)}
    return exc.filename in names and exc.filename2 in names


def _remove_dead_temporaries(parent: Path, name: str) -> None:
    """Temporary files of ``name`` left by killed processes (``.NAME.PID.XXXXXXXX.tmp``) go before a new write."""
    for path in parent.glob(f".{glob.escape(name)}.*.tmp"):
        pid = path.name[len(name) + 2:].split(".", 1)[0]
        if (pid.isdigit() and _TEMP_FILE.match(path.name) and not pid_alive(int(pid))
                and foreign_reason(path, folder=False) is None):  # another user's file of that name is left alone
            with contextlib.suppress(OSError):
                path.unlink()


def write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    with atomic_open(path, "wb") as handle:
        handle.write(data)
    return Path(path)


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    with atomic_open(path, "w", newline="\n") as handle:
        handle.write(text)
    return Path(path)


def write_csv(path: str | os.PathLike[str], frame, *, for_people: bool = True, **to_csv_kwargs) -> Path:
    """Write a pandas DataFrame as CSV atomically (no index unless asked). A CSV for people is opened in a
    spreadsheet, so its text cells are made formula-safe (``text.spreadsheet_safe``); a study folder's own tables
    (``for_people=False``) are data, read back as written."""
    if for_people:
        frame = spreadsheet_safe(frame)
    to_csv_kwargs.setdefault("index", False)
    to_csv_kwargs.setdefault("lineterminator", "\n")
    with atomic_open(path, "w") as handle:
        frame.to_csv(handle, **to_csv_kwargs)
    return Path(path)


# --------------------------------------------------------------------------- whole folders
#
# A study or a report is many files that only make sense together, so it is never rewritten file by file in
# place: it is built in a sibling folder on the same file system, whose name says it is roughsense's own
# unfinished work (``.NAME.roughsense-partial-PID-XXXX``), and swapped in whole. A killed run leaves at worst
# such a sibling; the next run into the same target deletes it (its process is gone) without asking for --force.

PARTIAL_TAG = ".roughsense-partial-"
RETIRED_TAG = ".roughsense-retired-"
LOCK_TAG = ".roughsense-lock"  # _util/lock.py: who holds the claim of a running command on the folder of that name
FLOCK_SUFFIX = ".flock"  # _util/lock.py: ``.NAME.roughsense-lock.flock``, the file filelock holds the claim on
MAX_CARRIED_FILES = 1000  # beyond this, --out is somebody's working folder, not an output folder
_RENAME_EXCHANGE = 2  # linux/fs.h
_TEMP_FILE = re.compile(r"^\..+\.[a-z0-9_]{8}\.tmp$")  # mkstemp in atomic_open (older versions: no PID)


def is_temporary(path: str | os.PathLike[str]) -> bool:
    """True for a temporary file of :func:`atomic_open` (``.NAME.PID.XXXXXXXX.tmp``), a staging/retired folder or a
    lock's files (``.NAME.roughsense-lock`` and ``.NAME.roughsense-lock.flock``)."""
    name = Path(path).name
    return (bool(_TEMP_FILE.match(name)) or PARTIAL_TAG in name or RETIRED_TAG in name
            or (name.startswith(".") and name.endswith((LOCK_TAG, LOCK_TAG + FLOCK_SUFFIX))))


def pid_alive(pid: int) -> bool:
    """Whether a process of that PID runs (another user's counts: it cannot be signalled, but it is there)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists but is not ours (EPERM)
        return True
    return True


def _swap_target(target: str | os.PathLike[str]) -> Path:
    """The real folder to replace: absolute, a symlinked folder replaced where it really lives -- if the link is
    the user's own: another user's link could point the swap at a folder of the victim's."""
    path = Path(os.path.abspath(target))
    if not path.is_symlink():
        return path
    if os.lstat(path).st_uid != os.geteuid():
        raise OutputExistsError("is a symbolic link made by another user; delete it or choose another output "
                                "folder (roughsense follows only your own links)", path=path)
    return Path(os.path.realpath(path))


def leftovers(target: str | os.PathLike[str]) -> list[Path]:
    """Staging and retired siblings of ``target`` left by roughsense runs that are no longer running."""
    target = _swap_target(target)
    found = []
    for tag in (PARTIAL_TAG, RETIRED_TAG):
        for path in target.parent.glob(f".{glob.escape(target.name)}{tag}*"):
            pid = path.name[len(target.name) + 1 + len(tag):].split("-", 1)[0]
            if pid.isdigit() and not pid_alive(int(pid)):
                found.append(path)
    return sorted(found)


def clean_leftovers(target: str | os.PathLike[str]) -> None:
    """Finish what a killed run left beside ``target``.

    A retired folder when ``target`` is missing is the previous content, caught between the two renames of a
    swap without ``renameat2``: it is put back. Everything else of roughsense's own is deleted. A leftover's name
    can be planted by anyone who can write the parent folder (a link to a private folder would be put back as the
    output), so one that is not a real folder of this user's is refused, never renamed, followed or deleted.
    """
    import shutil

    target = _swap_target(target)
    found = leftovers(target)
    for path in found:
        if (reason := foreign_reason(path, folder=True)) is not None:
            raise OutputExistsError(f"{path.name} beside it looks like a leftover of a roughsense run but {reason}, "
                                    f"so roughsense did not make it; delete {path} (or choose another output folder)",
                                    path=target)
    for path in found:
        if RETIRED_TAG in path.name and not target.exists() and not target.is_symlink():
            try:
                os.rename(path, target)
                continue
            except OSError:
                pass
        shutil.rmtree(path, ignore_errors=True)


def foreign_files(target: Path, owned) -> list[Path]:
    """Paths under ``target`` (relative) that ``owned`` does not claim: what a user put there."""
    found: list[Path] = []
    if not target.is_dir():
        return found
    for folder, dirs, files in os.walk(target):
        rel_folder = Path(folder).relative_to(target)
        for name in list(dirs):
            rel = rel_folder / name
            if owned(rel) or os.path.islink(os.path.join(folder, name)):
                dirs.remove(name)
                if not owned(rel):
                    found.append(rel)  # a symlinked folder is carried over as a link, never followed
            elif not any(os.scandir(os.path.join(folder, name))):
                found.append(rel)  # an empty folder of the user's
        for name in files:
            rel = rel_folder / name
            if not owned(rel) and not is_temporary(rel):
                found.append(rel)
    return found


def _carry_over(old: Path, new: Path, owned) -> None:
    """Give ``new`` the user's files of ``old`` as hard links (copies across devices): both hold them until the swap."""
    import shutil

    for rel in foreign_files(old, owned):
        src, dst = old / rel, new / rel
        if dst.exists() or dst.is_symlink():
            continue  # roughsense writes this name itself: the new one wins (the user passed --force)
        dst.parent.mkdir(parents=True, exist_ok=True)
        if src.is_symlink():
            os.symlink(os.readlink(src), dst)
        elif src.is_dir():
            dst.mkdir()
        else:
            try:
                os.link(src, dst)
            except OSError:
                shutil.copy2(src, dst)


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swap two paths (Linux renameat2 RENAME_EXCHANGE); False where that is not available."""
    import ctypes
    import sys

    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd = -100
    result = renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), ctypes.c_uint(_RENAME_EXCHANGE))
    return result == 0


class FolderSwap:
    """Build a replacement for the folder ``target`` beside it, then swap it in whole.

    ``owned(relative_path)`` says which entries of the old folder are roughsense's output (they are replaced);
    every other entry is a user's and is carried into the new folder (hard links, so both folders hold it until
    the swap). Creating the staging folder first doubles as the check that ``target`` can be written at all.
    """

    def __init__(self, target: str | os.PathLike[str], *, owned=lambda rel: True) -> None:
        import weakref

        self.target = _swap_target(target)
        self.owned = owned
        if self.target.exists() and not self.target.is_dir():
            raise OutputExistsError("exists and is not a folder", path=Path(target))
        try:
            cwd = Path.cwd().resolve()
        except OSError:  # the working folder was deleted: it cannot be inside the target
            cwd = None
        if self.target.exists() and cwd is not None and cwd.is_relative_to(self.target.resolve()):
            raise OutputExistsError("is the folder you are working in (or holds it); choose another output folder",
                                    path=Path(target))
        carried = foreign_files(self.target, owned)
        if len(carried) > MAX_CARRIED_FILES:
            raise OutputExistsError(f"holds {len(carried)} files that roughsense did not write; choose an output "
                                    "folder of its own", path=Path(target))
        clean_leftovers(self.target)
        try:
            self.target.parent.mkdir(parents=True, exist_ok=True)
            self.path = Path(tempfile.mkdtemp(prefix=f".{self.target.name}{PARTIAL_TAG}{os.getpid()}-",
                                              dir=self.target.parent))
            os.chmod(self.path, 0o777 & ~_umask())
        except OSError as exc:
            raise RoughsenseError(f"cannot write here: {exc.strerror or exc}", path=Path(target)) from None
        self._cleanup = weakref.finalize(self, _remove_if_owner, str(self.path), os.getpid())

    def commit(self) -> Path:
        """Swap the built folder in; the old content (minus the user's files, carried over) is then deleted."""
        import shutil

        try:
            interrupt.check()  # a run asked to stop commits nothing more (abort() removes the staging folder)
            _carry_over(self.target, self.path, self.owned)
            if not self.target.exists():
                os.rename(self.path, self.target)
            elif self.target.is_dir() and not any(self.target.iterdir()):
                os.rmdir(self.target)
                os.rename(self.path, self.target)
            elif _exchange(self.path, self.target):
                pass  # self.path now holds the old folder, still under roughsense's partial name
            else:
                # Killed between these two renames, the next run finds no target and puts the retired one back.
                retired = self.target.parent / f".{self.target.name}{RETIRED_TAG}{os.getpid()}-{secrets.token_hex(4)}"
                os.rename(self.target, retired)
                os.rename(self.path, self.target)
                os.rename(retired, self.path)
        except interrupt.Interrupted:
            self.abort()
            raise
        except OSError as exc:
            self.abort()
            raise RoughsenseError(f"cannot replace the folder: {exc.strerror or exc}", path=self.target) from None
        self._cleanup.detach()
        shutil.rmtree(self.path, ignore_errors=True)
        return self.target

    def abort(self) -> None:
        self._cleanup()


@contextlib.contextmanager
def staged_folder(target: str | os.PathLike[str] | FolderSwap, *, owned=None) -> Iterator[Path]:
    """``with staged_folder(out) as tmp:`` write everything into ``tmp``; on a clean exit it becomes ``out``.

    On an exception nothing changes at ``out``; on a kill, a ``.out.roughsense-partial-*`` sibling remains and
    the next run into ``out`` removes it. ``target`` may be a :class:`FolderSwap` made earlier, so that an
    unwritable place fails before long work rather than after it.
    """
    if isinstance(target, FolderSwap) and owned is not None:
        raise TypeError("staged_folder: a FolderSwap already says what it owns; pass owned= to FolderSwap")
    swap = target if isinstance(target, FolderSwap) else FolderSwap(target, owned=owned or (lambda rel: True))
    try:
        yield swap.path
    except BaseException:
        swap.abort()
        raise
    swap.commit()


def _remove_if_owner(path: str, pid: int) -> None:
    """Delete a staging folder, but only from the process that made it (never from a forked worker's copy)."""
    import shutil

    if os.getpid() == pid:
        shutil.rmtree(path, ignore_errors=True)

