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
        self.start()
        return self

    def start(self) -> None:
        """Start `echogym serve` (again, e.g. after `kill -9` of the last one) and wait
        until it answers; RuntimeError if it exits or does not answer in 30 s."""
        binary = os.environ.get("ECHOGYM_BIN")
        command = [binary] if binary else [sys.executable, "-m", "echogym"]
        self.process = subprocess.Popen(
            [*command, "serve", "--name", self.name,
             "--log", os.environ.get("ECHOGYM_BENCH_SERVER_LOG", "warn"), *self.extra],
            stdin=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 30
        while True:
            try:
                _native.NativeClient(self.name)
                if self.process.poll() is None:
                    return
            except _native.ServerNotRunningError:
                pass
            if self.process.poll() is not None:
                raise RuntimeError(f"benchmark server exited with {self.process.returncode}")
            if time.monotonic() > deadline:
                raise RuntimeError("benchmark server did not start in 30 s")
            time.sleep(0.02)

    def __exit__(self, *exc) -> None:
        self.process.send_signal(signal.SIGTERM)
        self.process.wait(timeout=30)
        _native.remove_location(self.prefix, self.root)
