"""Faults reach Python as typed errors: a step that outlives its deadline raises
ControlTimeoutError, an env that panics raises EnvFailureError, and the server lives on.
Uses `echogym/Faulty-v0`, registered by `echogym serve --fault-injection`."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from conftest import Server
from echogym import _native
from echogym.errors import ControlTimeoutError, EnvFailureError


def test_a_stalled_step_times_out_and_a_panic_is_an_env_failure(ipc, monkeypatch):
    server = Server("pytest", ipc, "--fault-injection")
    monkeypatch.setenv("ECHOGYM_STEP_TIMEOUT_S", "0.3")
    client = _native.NativeClient("pytest")
    stalled = client.attach("echogym/Faulty-v0", 1, json.dumps({"stall_ms": 2000}))
    stalled.reset()
    started = time.monotonic()
    with pytest.raises(ControlTimeoutError, match="ECHOGYM_STEP_TIMEOUT_S"):
        stalled.step(np.zeros((1, 1), np.float32))
    assert time.monotonic() - started < 1.5

    # Faulty envs are numbered over the server's life: the stalled one was env 0.
    panicky = client.attach(
        "echogym/Faulty-v0", 2, json.dumps({"panic_in": "step", "env_index": 2})
    )
    panicky.reset()
    with pytest.raises(EnvFailureError):
        panicky.step(np.zeros((2, 1), np.float32))
    panicky.reset()  # the failed env is reset; the lease lives
    panicky.close()
    stalled.close()
    del stalled, panicky, client
    assert server.stop() == 0
