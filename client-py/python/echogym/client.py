"""Connecting to a server and leasing envs: the layer the gymnasium and torchrl adapters use."""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np

from echogym._native import NativeAsyncBatch, NativeClient, NativeLease
from echogym.private_server import connect_or_start

DEFAULT_SERVER = "default"


def default_server_name() -> str:
    """`$ECHOGYM_SERVER`, else ``"default"``."""
    return os.environ.get("ECHOGYM_SERVER", DEFAULT_SERVER)


class Client:
    """A connection to one echogym server.

    Create with :func:`connect`. Cheap to keep around; leases keep it alive.
    """

    def __init__(self, native: NativeClient) -> None:
        self.native = native

    @property
    def name(self) -> str:
        """The server name."""
        return self.native.name

    def request(self, op: str, **fields: Any) -> dict[str, Any]:
        """Send a control request (``op`` is ``status``, ``list_envs``, ``spec``, ``stop``, ...)."""
        return json.loads(self.native.request(json.dumps({"op": op, **fields})))

    def status(self) -> dict[str, Any]:
        """The server's status: pid, uptime, leases, counters."""
        return self.request("status")

    def list_envs(self) -> list[dict[str, str]]:
        """The env ids the server can host."""
        return self.request("list_envs")["envs"]

    def stop(self) -> None:
        """Ask the server to stop gracefully."""
        self.request("stop")

    def attach(
        self,
        env_id: str,
        num_envs: int = 1,
        config: dict[str, Any] | None = None,
        autoreset_mode: str = "disabled",
    ) -> NativeLease:
        """Lease ``num_envs`` envs of ``env_id``; see :class:`echogym._native.NativeLease`."""
        return self.native.attach(env_id, num_envs, json.dumps(config or {}), autoreset_mode)

    def attach_async(
        self,
        env_id: str,
        num_envs: int,
        group_size: int,
        config: dict[str, Any] | None = None,
        autoreset_mode: str = "disabled",
    ) -> NativeAsyncBatch:
        """Lease ``num_envs`` envs as groups of ``group_size`` (one lease each) for
        asynchronous stepping; see :class:`echogym._native.NativeAsyncBatch`."""
        return self.native.attach_async(
            env_id, num_envs, group_size, json.dumps(config or {}), autoreset_mode
        )


def connect(
    name: str | None = None,
    *,
    autostart: bool = False,
    prefix: str | None = None,
    root: str | None = None,
    spin_us: int | None = None,
    label: str | None = None,
) -> Client:
    """Attach to the running server ``name`` (default ``$ECHOGYM_SERVER`` or ``"default"``).

    With ``autostart=True`` a private server is started when none is running, and
    stopped when this process exits. ``prefix``/``root`` select the iceoryx2 location
    (default ``$ECHOGYM_IPC_PREFIX`` / ``$ECHOGYM_IPC_ROOT``); ``spin_us`` is how long
    to busy-poll for an answer before blocking (default ``$ECHOGYM_SPIN_US`` or 200).

    Raises :class:`echogym.ServerNotRunningError` when no server runs and ``autostart``
    is false.
    """
    name = name or default_server_name()
    spin = spin_us if spin_us is not None else int(os.environ.get("ECHOGYM_SPIN_US", "200"))
    label = label or f"pid {os.getpid()} python"
    if autostart:
        native = connect_or_start(name, prefix, root, spin, label)
    else:
        native = NativeClient(name, prefix, root, spin, label)
    return Client(native)


def as_actions(action: Any) -> np.ndarray:
    """``action`` ready for :meth:`NativeLease.step`: floating arrays (any width, lists of
    floats) as C-contiguous float32, anything else unchanged.

    This converts, it does not check: the lease is the one check of dtype and shape (and
    of finite values), raising :class:`echogym.InvalidActionError` naming what it got.
    """
    array = np.asarray(action)
    if array.dtype.kind == "f":
        return np.ascontiguousarray(array, dtype=np.float32)
    return array
