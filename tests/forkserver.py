"""A fork server for tests that run many ``roughsense`` commands through a shell (the tutorial).

Each command still runs as a process of its own: its own pid, the shell's stdin, stdout and stderr (passed over a
Unix socket), its working folder and environment, and its exit status back to the shell. What it skips is the
interpreter start-up: the process is forked from a server that has already imported the third-party libraries the
CLI loads (NumPy, pandas, SciPy, scikit-learn, ...: about 1.5 s of CPU per command), then runs ``python -m
roughsense.cli`` in it with ``runpy``. No roughsense module but ``roughsense.cli`` itself is imported ahead, so a
command imports the package's modules as a fresh interpreter would.

This file is the pytest side (:func:`fork_server`), the server (``python forkserver.py serve SOCKET``) and the
client the shim on PATH execs (``python -I -S forkserver.py client SOCKET ARGS...``, standard library only, so it
starts in milliseconds). Commands are not signalled through the client (Ctrl-C on the shell): tests of signals and
of a fresh interpreter's behaviour start real ``roughsense`` processes instead.
"""
from __future__ import annotations

import array
import contextlib
import json
import os
import select
import socket
import struct
import subprocess
import sys
import tempfile

#: What the server imports before it listens: the third-party libraries behind the CLI's commands.
PRELOAD = ("numpy", "pandas", "scipy.stats", "scipy.signal", "sklearn.base", "sklearn.utils.validation", "PIL.Image",
           "cv2", "joblib", "typer", "rich.console", "roughsense.cli")
_HEADER = struct.Struct("!I")
_STATUS = struct.Struct("!i")
_STDIO = (0, 1, 2)


@contextlib.contextmanager
def fork_server(env: dict[str, str]):
    """A running server whose commands see ``env`` (also the server's own environment, so that anything a library
    reads from the environment at import time is what a fresh interpreter would read); yields the ``roughsense``
    shim's text. The server is stopped at exit."""
    folder = tempfile.mkdtemp(prefix="rs-fork-")  # short: a Unix socket's path has at most 107 bytes
    path = os.path.join(folder, "socket")
    server = subprocess.Popen([sys.executable, __file__, "serve", path], env=env, stdin=subprocess.DEVNULL,
                              stdout=subprocess.PIPE, text=True)
    try:
        ready = server.stdout.readline()
        assert ready == "ready\n", f"the fork server did not start ({server.wait()})"
        yield f'#!/bin/sh\nexec "{sys.executable}" -I -S "{__file__}" client "{path}" "$@"\n'
    finally:
        server.terminate()
        server.wait()
        server.stdout.close()
        with contextlib.suppress(OSError):
            os.unlink(path)
        os.rmdir(folder)


def serve(path: str) -> None:
    """Import PRELOAD, listen on ``path`` and fork a child per request; each child's exit status goes back to its
    client. Never returns in a child: the command's ``SystemExit`` ends it as it ends ``python -m``."""
    import importlib

    for name in PRELOAD:
        importlib.import_module(name)
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(path)
    listener.listen(8)
    print("ready", flush=True)
    waiting: dict[int, socket.socket] = {}  # child pid -> its client's connection
    while True:
        readable, _, _ = select.select([listener], [], [], 0.02 if waiting else None)
        if readable:
            conn, _ = listener.accept()
            request, fds = _receive(conn)
            pid = os.fork()
            if pid == 0:
                for other in (listener, conn, *waiting.values()):
                    other.close()
                _run(request, fds)
            for fd in fds:
                os.close(fd)
            waiting[pid] = conn
        for pid in list(waiting):
            done, status = os.waitpid(pid, os.WNOHANG)
            if done:
                conn = waiting.pop(pid)
                with contextlib.suppress(OSError):
                    conn.sendall(_STATUS.pack(os.waitstatus_to_exitcode(status)))
                conn.close()


def _receive(conn: socket.socket) -> tuple[dict, list[int]]:
    """One request (argv, cwd, environment) and the client's stdin, stdout and stderr."""
    fds = array.array("i")
    data, ancillary, _, _ = conn.recvmsg(65536, socket.CMSG_SPACE(len(_STDIO) * fds.itemsize))
    for level, kind, payload in ancillary:
        if level == socket.SOL_SOCKET and kind == socket.SCM_RIGHTS:
            fds.frombytes(payload[:len(payload) - len(payload) % fds.itemsize])
    (size,) = _HEADER.unpack_from(data)
    while len(data) < _HEADER.size + size:
        data += conn.recv(65536)
    return json.loads(data[_HEADER.size:]), list(fds)


def _run(request: dict, fds: list[int]) -> None:
    """In the forked child: become the client's process (stdio, folder, environment, argv) and run the CLI."""
    import runpy

    for target, fd in zip(_STDIO, fds):
        os.dup2(fd, target)
        os.close(fd)
    os.chdir(request["cwd"])
    os.environ.clear()
    os.environ.update(request["env"])
    sys.argv = list(request["argv"])
    runpy.run_module("roughsense.cli", run_name="__main__", alter_sys=True)
    sys.exit(0)


def client(path: str, args: list[str]) -> int:
    """Send this process's argv, folder, environment and stdio to the server; its command's exit status."""
    payload = json.dumps({"argv": ["roughsense", *args], "cwd": os.getcwd(), "env": dict(os.environ)}).encode()
    message = _HEADER.pack(len(payload)) + payload
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as conn:
        conn.connect(path)
        sent = conn.sendmsg([message], [(socket.SOL_SOCKET, socket.SCM_RIGHTS, array.array("i", _STDIO))])
        conn.sendall(message[sent:])
        status = b""
        while len(status) < _STATUS.size and (chunk := conn.recv(_STATUS.size)):
            status += chunk
    if len(status) < _STATUS.size:
        print("roughsense (test fork server): the server went away", file=sys.stderr)
        return 1
    (code,) = _STATUS.unpack(status)
    return code if code >= 0 else 128 - code  # killed by signal N: 128 + N, as a shell reports it


if __name__ == "__main__":
    if sys.argv[1] == "serve":
        serve(sys.argv[2])
    else:
        sys.exit(client(sys.argv[2], sys.argv[3:]))
