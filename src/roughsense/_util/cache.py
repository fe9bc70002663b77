"""Where roughsense keeps what it can recompute: the built-in simulated study and extracted features.

The cache is ``$ROUGHSENSE_CACHE_DIR``, else the platform's user cache folder as platformdirs knows it (on Linux
``$XDG_CACHE_HOME/roughsense``, else ``~/.cache/roughsense``; on macOS ``~/Library/Caches/roughsense``).
A whole folder (the built-in study) is an entry named by its stem and version (:func:`cached_folder`): the caller
says how to build it, so this layer knows nothing of the simulator.
Entries are keyed by content, so a stale entry is never reused: features are keyed by every input that shapes
the cached frame -- manifest.csv and study.toml as written, the manifest as read (with each image's condition),
the sensor settings and every image's size, mtime, ctime and inode; each entry carries a checksum and one
that fails it is recomputed.
"""
from __future__ import annotations

import contextlib
import glob
import hashlib
import io
import json
import os
import shutil
import stat
import warnings
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from ..errors import RoughsenseError, RoughsenseWarning
from . import atomic
from .files import foreign_reason, kind_of, read_regular


def cache_dir() -> Path:
    """``$ROUGHSENSE_CACHE_DIR``, else the platform's user cache folder (platformdirs) for roughsense."""
    explicit = os.environ.get("ROUGHSENSE_CACHE_DIR")
    if explicit:
        return Path(explicit)
    from platformdirs import user_cache_dir

    return Path(user_cache_dir("roughsense", appauthor=False))


_BYPASS_SAID: set[str] = set()  # cache folders this process has said it bypasses (once each)


def usable_cache_dir() -> Path | None:
    """The cache folder if it can be trusted, else None (said once per folder, as a warning).

    A cache is read back as results, so anyone who can write it can choose the numbers a run reports: it is
    created 0700 and used only while it is a real folder of this user's that no one else can write.
    """
    root = cache_dir()
    try:
        root.parent.mkdir(parents=True, exist_ok=True)
        with contextlib.suppress(FileExistsError):
            root.mkdir(mode=0o700)
        info = os.lstat(root)
    except OSError as exc:
        return _bypass(root, f"cannot be made ({exc.strerror or exc})")
    if not stat.S_ISDIR(info.st_mode):
        return _bypass(root, f"is {kind_of(info.st_mode)}, not a folder")
    if info.st_uid != os.geteuid():
        return _bypass(root, f"belongs to another user (uid {info.st_uid}), who could choose its results")
    if info.st_mode & 0o022:
        return _bypass(root, f"can be written by other users (mode {stat.S_IMODE(info.st_mode):o}), who could choose "
                             "its results; chmod go-w it to use it")
    if (above := _swappable_parent(root)) is not None:
        return _bypass(root, f"lies in {above}, which other users can write without the sticky bit (or own): they "
                             "could swap the cache folder for their own between two looks")
    return root


def _swappable_parent(root: Path) -> Path | None:
    """The first folder above ``root`` in which another user could rename ``root`` (or a folder holding it) away and
    put their own in its place: owned by another user than this one or root, or writable by others and not
    sticky (``/tmp`` is sticky: only an entry's owner may rename it)."""
    folder = Path(os.path.realpath(root.parent))
    for above in (folder, *folder.parents):
        try:
            info = os.stat(above)
        except OSError:
            return above
        if info.st_uid not in (0, os.geteuid()) or (info.st_mode & 0o022 and not info.st_mode & stat.S_ISVTX):
            return above
    return None


def _bypass(root: Path, reason: str) -> None:
    if str(root) not in _BYPASS_SAID:
        _BYPASS_SAID.add(str(root))
        warnings.warn(RoughsenseWarning(f"the cache folder {root} {reason}: not using it, so everything is "
                                        "computed afresh (set ROUGHSENSE_CACHE_DIR to a folder of your own)"),
                      stacklevel=3)
    return None


#: Bumped whenever what an entry holds changes: older entries are then simply not found.
CACHE_FORMAT = 4  # 4: features hold the contact measures (issue 46); a change to their reading bumps it
_CHECKSUM_PREFIX = b"#sha256="


def image_fingerprint(path: Path) -> str:
    """What identifies one image's bytes without reading them: size, mtime_ns, ctime_ns, inode and device.

    ``ctime`` cannot be set back by a user (``touch -d`` and ``os.utime`` move only atime and mtime, and
    themselves update ctime), so an image rewritten in place with its old mtime restored still gets a new key.
    """
    stat = path.stat()
    return f"{stat.st_size}:{stat.st_mtime_ns}:{stat.st_ctime_ns}:{stat.st_ino}:{stat.st_dev}"


def features_key(study, feature_definition: dict) -> str:
    """The key of a study's features: a change to any file or setting that shapes the frame gives a new key."""
    digest = hashlib.sha256()
    digest.update(f"format {CACHE_FORMAT}\n".encode())
    digest.update(str(Path(study.root).resolve()).encode())
    digest.update(json.dumps(feature_definition, sort_keys=True, default=str).encode())
    for name in ("manifest.csv", "study.toml"):  # study.toml's [protocol] forces_n labels each image's condition
        path = Path(study.root) / name
        digest.update(f"{name}\0".encode() + (path.read_bytes() if path.is_file() else b"") + b"\0")
    digest.update(study.manifest.to_csv(index=False, lineterminator="\n", float_format="%.17g").encode())
    for relative, path in zip(study.manifest["image"], study.image_paths):
        digest.update(f"{relative}\0{image_fingerprint(path)}\n".encode())
    return digest.hexdigest()[:24]


def _verified_body(raw: bytes) -> bytes | None:
    """The entry's CSV if its trailing checksum line matches it, else None (truncated, edited or damaged)."""
    cut = raw.rfind(b"\n" + _CHECKSUM_PREFIX)
    if cut < 0 or not raw.endswith(b"\n"):
        return None
    body, trailer = raw[: cut + 1], raw[cut + 1 :].strip()
    expected = trailer[len(_CHECKSUM_PREFIX):].decode("ascii", errors="replace")
    return body if hashlib.sha256(body).hexdigest() == expected else None


def cached_frame(key: str, compute: Callable[[], pd.DataFrame], *, kind: str = "features") -> tuple[pd.DataFrame, bool]:
    """Return (frame, was_cached). Stored as pickle-free CSV with text columns kept as text.

    Each entry ends with a line holding the SHA-256 of the CSV above it. An entry that fails it (cut short by
    a full disk, damaged, edited) is recomputed and replaced, never trusted: a bad cache must not produce an
    error that blames the user's correct files.
    """
    root = usable_cache_dir()
    if root is None:
        return compute(), False
    path = root / kind / f"{key}.csv"
    if foreign_reason(path.parent, folder=True) is None and foreign_reason(path, folder=False) is None:
        try:
            body = _verified_body(read_regular(path, own=True))  # the owner again, on the descriptor
            if body is not None:
                frame = pd.read_csv(io.BytesIO(body), dtype={"image": str, "specimen": str, "pad": str, "condition": str},
                                    keep_default_na=False, na_values=[""])
                return frame, True
        except (OSError, ValueError, pd.errors.ParserError, RoughsenseError):
            pass  # a damaged cache entry is simply recomputed
    frame = compute()
    try:
        body = frame.to_csv(index=False, lineterminator="\n", float_format="%.17g").encode("utf-8")
        atomic.write_bytes(path, body + _CHECKSUM_PREFIX + hashlib.sha256(body).hexdigest().encode() + b"\n")
    except Exception:  # the cache is an optimisation: never fail the run because it cannot be written
        pass
    return frame, False


def folder_entry(stem: str, version: str) -> Path:
    """Where the cached folder ``stem`` of ``version`` lives (or will live)."""
    return cache_dir() / f"{stem}-{version}"


#: The file the builder of a cached folder writes into it, holding the entry's key (its name): the one mark by which
#: the cache knows a folder as its own. A folder without it, or holding another key (a copy renamed), or of another
#: user's, or a link, is a user's: it is never reused, replaced or deleted.
KEY_FILE = ".roughsense-cache-key"


def key_files(entry: Path) -> dict[str, str]:
    """What a builder writes into the folder ``entry`` before anything else (name -> text): its key."""
    return {KEY_FILE: f"{entry.name}\n"}


def made_here(folder: Path, key: str) -> bool:
    """Whether ``folder`` is a cache folder the builder made for ``key``: a real folder of this user's (lstat, never
    followed) holding :data:`KEY_FILE`, a regular file of this user's whose text is ``key``."""
    try:
        if not stat.S_ISDIR(os.lstat(folder).st_mode) or foreign_reason(folder, folder=True) is not None:
            return False
        if foreign_reason(folder / KEY_FILE, folder=False) is not None:
            return False
        return read_regular(folder / KEY_FILE, limit=1000, own=True) == f"{key}\n".encode()
    except (OSError, RoughsenseError):
        return False


def cached_folder(stem: str, version: str, build: Callable[[Path, dict[str, str]], object], *,
                  is_complete: Callable[[Path], bool]) -> Path:
    """The folder ``stem`` of ``version``, built by ``build(path, key_files)`` once and reused while ``is_complete``
    says so.

    ``build`` writes ``key_files`` (:func:`key_files`) into the folder first, writes beside the entry and swaps it
    in whole, so a killed run leaves no entry (only a partial sibling the next call removes), never a half-written
    one that later runs would trust. The cache finds its entries by that key alone (:func:`made_here`): complete
    entries of other versions are its own and never read again, so they are removed; a folder under any of these
    names that the builder did not make is a user's, never touched: the entry is then built in a private folder
    of this run's instead.
    """
    cache = usable_cache_dir()
    root = None if cache is None else folder_entry(stem, version)
    if root is not None and made_here(root, root.name) and is_complete(root):
        return root
    if root is not None and (os.path.lexists(root) and not made_here(root, root.name)):
        warnings.warn(RoughsenseWarning(f"{root} was not made by roughsense (no {KEY_FILE} of its own in it), so it is "
                                        "left as it is and the entry is built afresh in a temporary folder; move it "
                                        "away to let the cache keep the entry"), stacklevel=2)
        root = None
    if root is None:  # an untrusted cache, or a user's folder in the entry's place: a private folder of this run's
        import atexit
        import tempfile

        root = Path(tempfile.mkdtemp(prefix=f"roughsense-{stem}-")) / stem
        atexit.register(shutil.rmtree, root.parent, ignore_errors=True)
        build(root, key_files(root))
        return root
    _remove_own(cache, stem, keep=root)
    build(root, key_files(root))
    return root


def _remove_own(cache: Path, stem: str, *, keep: Path) -> None:
    """The cache's own entries of ``stem`` other than ``keep``, and its killed runs' partial ones: only those whose
    key the builder wrote (:func:`made_here`); every other folder is a user's and stays."""
    for stale in cache.glob(f"{glob.escape(stem)}-*"):
        if stale != keep and made_here(stale, stale.name):
            shutil.rmtree(stale, ignore_errors=True)
    for partial in cache.glob(f".{glob.escape(stem)}-*{atomic.PARTIAL_TAG}*"):  # killed runs, any version
        target = partial.parent / partial.name[1:].split(atomic.PARTIAL_TAG)[0]
        with contextlib.suppress(RoughsenseError):  # a link planted at the target's name: nothing of ours to clean
            if made_here(partial, target.name) and partial in atomic.leftovers(target):
                shutil.rmtree(partial, ignore_errors=True)
