"""A private `echogym serve` for benchmarks (own ipc prefix, stopped at the end)."""

from __future__ import annotations

import os
import platform
import signal
import subprocess
import sys
import time

from echogym import _native


def machine_description() -> str:
    """CPU model, core count and memory of this machine, for result tables."""
    model = platform.processor() or "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
        with open("/proc/meminfo") as f:
            mem_kb = int(f.readline().split()[1])
    except OSError:
        mem_kb = 0
    return f"{model}, {os.cpu_count()} cores, {mem_kb / 2**20:.0f} GiB"


class BenchServer:
    """Context manager running `echogym serve --name NAME` in a private ipc location."""

    def __init__(self, name: str, *extra: str) -> None:
        self.name = name
        self.extra = extra
        tag = f"egb{os.getpid()}"
        self.prefix, self.root = f"{tag}_", f"/tmp/echogym-bench-{tag}/"

    def __enter__(self) -> "BenchServer":
        os.environ["ECHOGYM_IPC_PREFIX"] = self.prefix
        os.environ["ECHOGYM_IPC_ROOT"] = self.root
        os.environ["ECHOGYM_SERVER"] = self.name
        binary = os.environ.get("ECHOGYM_BIN")
        command = [binary] if binary else [sys.executable, "-m", "echogym"]
        self.process = subprocess.Popen(
            [*command, "serve", "--name", self.name, "--log", "warn", *self.extra],
            stdin=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 30
        while True:
            try:
                _native.NativeClient(self.name)
                return self
            except _native.ServerNotRunningError:
                if time.monotonic() > deadline or self.process.poll() is not None:
                    raise RuntimeError("benchmark server did not start")
                time.sleep(0.02)

    def __exit__(self, *exc) -> None:
        self.process.send_signal(signal.SIGTERM)
        self.process.wait(timeout=30)
        _native.remove_location(self.prefix, self.root)
