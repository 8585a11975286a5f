"""A ``pmaccuracy`` for the documentation examples that imports once and forks per command.

The documentation examples (``tests/test_readme.py``) run about a hundred ``pmaccuracy`` commands through
``bash``; a fresh interpreter spends about half a second importing numpy, scipy, xarray, matplotlib and the
package before each one does its work. Here one server process imports them once and listens on a Unix socket;
the ``pmaccuracy`` on the examples' ``PATH`` is a small stdlib-only client that passes its standard input,
output and error (as file descriptors), its arguments, working folder and environment to the server, which
forks a child that becomes the command: the child puts the descriptors in place, changes folder, takes the
environment, runs :func:`pmaccuracy.cli.main` exactly as the console script does and reports the exit status
back. What a command prints, where and in which order, is what the installed console script prints (the same
buffering: the child's stdout is a pipe, as in a real run); only the import time is saved.

Run as ``python cli_forkserver.py SOCKET`` (the server); :func:`client_script` writes the client.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import struct
import sys
from pathlib import Path


def client_script(python: str, sock: str) -> str:
    """The text of the ``pmaccuracy`` client for the server at ``sock`` (stdlib only, started with ``-S``)."""
    return f"""#!{python} -S
import json, os, socket, struct, sys
s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
s.connect({sock!r})
msg = json.dumps({{"argv": sys.argv[1:], "cwd": os.getcwd(), "env": dict(os.environ)}}).encode()
socket.send_fds(s, [struct.pack("!I", len(msg)), msg], [0, 1, 2])
data = b""
while len(data) < 4:
    chunk = s.recv(4 - len(data))
    if not chunk:
        sys.exit(1)
    data += chunk
sys.exit(struct.unpack("!i", data)[0])
"""


def _recv_exactly(conn: socket.socket, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = conn.recv(n - len(data))
        if not chunk:
            raise ConnectionError("the client went away")
        data += chunk
    return data


def _child(conn: socket.socket, cli) -> None:
    """Become the command of the request on ``conn`` and exit (never returns)."""
    import atexit
    import traceback

    code = 1
    try:
        head, fds, _, _ = socket.recv_fds(conn, 4, 3)
        head += _recv_exactly(conn, 4 - len(head))
        req = json.loads(_recv_exactly(conn, struct.unpack("!I", head)[0]))
        signal.signal(signal.SIGCHLD, signal.SIG_DFL)
        for target, fd in zip((0, 1, 2), fds):
            os.dup2(fd, target)
            os.close(fd)
        os.chdir(req["cwd"])
        os.environ.clear()
        os.environ.update(req["env"])
        sys.argv = ["pmaccuracy", *req["argv"]]
        try:
            code = cli.main(req["argv"])
        except SystemExit as exc:
            if isinstance(exc.code, str):
                print(exc.code, file=sys.stderr)
                code = 1
            else:
                code = exc.code
        except BaseException:      # what the interpreter would print for an uncaught exception
            traceback.print_exc()
            code = 1
        atexit._run_exitfuncs()
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (BrokenPipeError, OSError):
                pass
    finally:
        try:
            conn.sendall(struct.pack("!i", int(code or 0)))
        finally:
            os._exit(0)


def serve(path: str) -> None:
    """Import what the commands use, then fork a child per connection on the Unix socket ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401
    import numpy  # noqa: F401
    import scipy.optimize  # noqa: F401
    import scipy.spatial  # noqa: F401
    import xarray  # noqa: F401

    import importlib
    import pkgutil

    import pmaccuracy
    import pmaccuracy.cli as cli

    for mod in pkgutil.walk_packages(pmaccuracy.__path__, "pmaccuracy."):   # the commands import lazily
        if mod.name.endswith("__main__"):
            continue
        try:
            importlib.import_module(mod.name)
        except Exception:   # an optional dependency missing: the command imports (and reports) it itself
            pass

    def reap(*_):
        while True:
            try:
                pid, _ = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                return
            if pid == 0:
                return

    signal.signal(signal.SIGCHLD, reap)
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    srv.bind(path)
    srv.listen(8)
    Path(path + ".ready").write_text("ready")
    while True:
        conn, _ = srv.accept()
        if os.fork() == 0:
            srv.close()
            _child(conn, cli)
        conn.close()


if __name__ == "__main__":
    serve(sys.argv[1])
