"""Auto-started private servers: spawned when no server is running, stopped at exit.

A private server is an ordinary `echogym serve` run by this Python interpreter
(`python -m echogym serve ...`, the server is linked into the native module). It is
started with `--exit-with-parent`, so it also stops if this process dies without
running its exit handlers (e.g. `kill -9`). Other processes may attach to it while it
runs; for long-lived multi-process set-ups, start `echogym serve` yourself.
"""

from __future__ import annotations

import atexit
import os
import subprocess
import sys
import tempfile
import threading
import time

from echogym._native import NativeClient, ServerNotRunningError

_lock = threading.Lock()
_started: dict[tuple[str, str | None, str | None], "PrivateServer"] = {}


class PrivateServer:
    """A server process this process started and will stop."""

    def __init__(self, name: str, prefix: str | None, root: str | None) -> None:
        self.name = name
        env = dict(os.environ)
        if prefix is not None:
            env["ECHOGYM_IPC_PREFIX"] = prefix
        if root is not None:
            env["ECHOGYM_IPC_ROOT"] = str(root)
        self.log_path = os.path.join(
            tempfile.gettempdir(), f"echogym-private-{name}-{os.getpid()}.log"
        )
        log = open(self.log_path, "ab")  # noqa: SIM115 (kept open by the child)
        self.process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "echogym",
                "serve",
                "--name",
                name,
                "--log",
                os.environ.get("ECHOGYM_LOG") or os.environ.get("RUST_LOG") or "warn",
                "--exit-with-parent",
                str(os.getpid()),
            ],
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=log,
            env=env,
        )
        log.close()

    def stop(self, timeout: float = 10.0) -> None:
        """SIGTERM the server and reap it (SIGKILL after `timeout` seconds)."""
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


def _stop_all() -> None:
    for server in list(_started.values()):
        server.stop()
    _started.clear()


atexit.register(_stop_all)


def connect_or_start(
    name: str,
    prefix: str | None,
    root: str | None,
    spin_us: int,
    label: str | None,
    timeout: float = 30.0,
) -> NativeClient:
    """Connect to server `name`, starting a private one if none is running."""
    try:
        return NativeClient(name, prefix, root, spin_us, label)
    except ServerNotRunningError:
        pass
    key = (name, prefix, root)
    with _lock:
        server = _started.get(key)
        if server is None or server.process.poll() is not None:
            server = PrivateServer(name, prefix, root)
            _started[key] = server
    deadline = time.monotonic() + timeout
    while True:
        try:
            return NativeClient(name, prefix, root, spin_us, label)
        except ServerNotRunningError:
            # Exit code 1 may mean another process won the race to start `name`:
            # keep trying to connect to theirs until the deadline.
            if time.monotonic() > deadline:
                raise ServerNotRunningError(
                    f"could not start a private echogym server named {name!r} within "
                    f"{timeout:.0f} s; see {server.log_path}"
                ) from None
            time.sleep(0.02)
