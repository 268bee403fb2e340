"""Fixtures: every test gets its own iceoryx2 location and, when asked, a real
`echogym serve` process (the server linked into the native module, run as
`python -m echogym serve`). Teardown checks that no shared memory was left behind."""

from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass

import pytest

from echogym import _native

_counter = itertools.count()


@dataclass
class Location:
    prefix: str
    root: str


class Server:
    """A real `echogym serve` process."""

    def __init__(self, name: str, location: Location, *extra: str) -> None:
        self.name = name
        self.location = location
        self.process = subprocess.Popen(
            [sys.executable, "-m", "echogym", "serve", "--name", name, "--log", "warn", *extra],
            stdin=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 30
        while True:
            try:
                _native.NativeClient(name)
                return
            except _native.ServerNotRunningError:
                if self.process.poll() is not None:
                    raise RuntimeError(f"server exited with {self.process.returncode}")
                if time.monotonic() > deadline:
                    raise RuntimeError("server did not come up")
                time.sleep(0.02)

    @property
    def pid(self) -> int:
        return self.process.pid

    def status(self) -> dict:
        client = _native.NativeClient(self.name)
        return json.loads(client.request(json.dumps({"op": "status"})))

    def stop(self) -> int:
        """SIGTERM and reap; the exit code."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
        return self.process.wait(timeout=15)

    def kill(self) -> None:
        """SIGKILL and reap."""
        self.process.kill()
        self.process.wait(timeout=15)


@pytest.fixture
def ipc(monkeypatch: pytest.MonkeyPatch):
    """A fresh iceoryx2 location, exported so clients and child processes use it."""
    tag = f"egp{os.getpid()}x{next(_counter)}"
    location = Location(prefix=f"{tag}_", root=f"/tmp/echogym-test-{tag}/")
    monkeypatch.setenv("ECHOGYM_IPC_PREFIX", location.prefix)
    monkeypatch.setenv("ECHOGYM_IPC_ROOT", location.root)
    monkeypatch.setenv("ECHOGYM_SERVER", "pytest")
    yield location
    import gc

    gc.collect()  # drop leases still referenced by test locals
    deadline = time.monotonic() + 5
    while (left := _native.leftover_segments(location.prefix)) and time.monotonic() < deadline:
        time.sleep(0.05)
    _native.remove_location(location.prefix, location.root)
    assert not left, f"shared memory left behind: {left}"


@pytest.fixture
def server(ipc: Location):
    """A running server named `pytest`, stopped (and checked to exit 0) afterwards."""
    srv = Server("pytest", ipc)
    yield srv
    if srv.process.poll() is None:
        import gc

        gc.collect()
        assert srv.stop() == 0


def run_python(code: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """Run `code` in a fresh interpreter with this test's environment."""
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout
    )
