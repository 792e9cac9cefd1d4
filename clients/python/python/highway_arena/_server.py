"""Starting a local arena-server for people (and tests) with none running."""

from __future__ import annotations

import collections
import contextlib
import os
import pathlib
import queue
import shutil
import socket
import subprocess
import threading
from dataclasses import dataclass


@dataclass
class LocalServer:
    """A running arena-server: connect to ``endpoint``."""

    endpoint: str
    process: subprocess.Popen


# Where a wheel built by scripts/build-wheel carries the server (see that script).
BUNDLED_SERVER = pathlib.Path(__file__).resolve().parent / "bin" / "arena-server"


def find_server_binary(binary=None) -> str:
    """The arena-server to start: ``binary``, else $ARENA_SERVER, else the one bundled in
    this package's wheel, else ``arena-server`` on PATH, else this repository's
    target/release/arena-server, then target/debug/arena-server."""
    if binary:
        return _executable(binary, "binary=")
    if os.environ.get("ARENA_SERVER"):
        return _executable(os.environ["ARENA_SERVER"], "$ARENA_SERVER")
    if BUNDLED_SERVER.is_file():
        return str(BUNDLED_SERVER)
    found = shutil.which("arena-server")
    if found:
        return found
    here = pathlib.Path(__file__).resolve()
    for root in [*here.parents, pathlib.Path.cwd()]:
        for profile in ("release", "debug"):
            candidate = root / "target" / profile / "arena-server"
            if candidate.is_file():
                return str(candidate)
    raise FileNotFoundError(
        "cannot find arena-server: install a wheel built with scripts/build-wheel (it carries one), "
        "build it with `cargo build --release -p arena-server`, put it on PATH, set $ARENA_SERVER, "
        "or pass binary=..."
    )


def _executable(path, named_by: str) -> str:
    """``path`` (a file, or a command on PATH) if it can be run; else an error naming
    where it came from, rather than the subprocess's bare "No such file"."""
    found = shutil.which(str(path))
    if found is None:
        raise FileNotFoundError(
            f"{named_by} {str(path)!r} is not an executable file: build one with "
            "`cargo build --release -p arena-server` and give its path (target/release/arena-server)"
        )
    return found


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def launch_server(binary=None, listen=None, args=(), timeout=30.0):
    """Starts an arena-server listening on ``listen`` (default: a free 127.0.0.1 port),
    yields a ``LocalServer`` once it serves, and stops it (SIGTERM) on exit. ``args``
    are more command-line flags (``["--scenarios", "my/scenarios"]``)."""
    endpoint = listen or f"tcp/127.0.0.1:{_free_port()}"
    command = [find_server_binary(binary), "--listen", endpoint, *map(str, args)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: queue.Queue = queue.Queue()
    # The server's stderr, read all the time (a full pipe would block the server); its
    # last lines explain a server that exits.
    errors: collections.deque = collections.deque(maxlen=50)

    def pump_stdout():
        for line in process.stdout:
            lines.put(line)
        lines.put(None)

    def pump_stderr():
        for line in process.stderr:
            if line.strip():
                errors.append(line.rstrip())

    readers = [threading.Thread(target=pump, daemon=True) for pump in (pump_stdout, pump_stderr)]
    for reader in readers:
        reader.start()
    try:
        while True:
            try:
                line = lines.get(timeout=timeout)
            except queue.Empty:
                raise TimeoutError(
                    f"arena-server did not start serving within {timeout} s: {' '.join(command)}"
                ) from None
            if line is None:
                process.wait()
                readers[1].join(timeout=5)
                raise RuntimeError(
                    f"arena-server exited (status {process.returncode}) before serving ({' '.join(command)}): "
                    + " / ".join(errors)
                )
            if "serving on" in line:
                break
        yield LocalServer(endpoint=endpoint, process=process)
    finally:
        if process.poll() is None:
            process.terminate()
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        for reader in readers:
            reader.join(timeout=5)
        for stream in (process.stdout, process.stderr):
            if stream:
                stream.close()


@contextlib.contextmanager
def serving(connect=None):
    """Yields ``connect`` when given (a running server's endpoint), else the endpoint of
    a server launched for the block: what scripts with a ``--connect`` option need."""
    if connect:
        yield connect
        return
    with launch_server() as server:
        yield server.endpoint
