"""Running test code as another user (nobody) in a forked child: the planted-file and shared-folder tests need a
second user, and root can become one without a second account."""
from __future__ import annotations

import os

import pytest

#: The user id (and group id) of Debian's nobody.
NOBODY = 65534


def as_nobody(action) -> str:
    """Run ``action()`` in a forked child as user nobody: its error as ``"Type: message"``, its result as text, or
    ``"ok"`` for None or a tuple."""
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child reports through the pipe
        os.close(read)
        try:
            os.setgid(NOBODY)
            os.setuid(NOBODY)
            result = action()
            text = "ok" if result is None or isinstance(result, tuple) else str(result)
        except BaseException as exc:
            text = f"{type(exc).__name__}: {exc}"
        os.write(write, text.encode())
        os._exit(0)
    os.close(write)
    os.waitpid(pid, 0)
    with os.fdopen(read, "rb") as handle:
        return handle.read().decode()


#: Acting as another user needs root (CI runs as root; a developer's run skips those tests).
AS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0
needs_root = pytest.mark.skipif(not AS_ROOT, reason="acting as another user needs root")
