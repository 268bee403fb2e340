"""Faults reach Python as typed errors or flags: a step that outlives its deadline raises
ControlTimeoutError; an env that panics fails alone — the other envs' results come back,
the failed env is flagged in ``info["env_error"]``, truncated and needs a reset — and the
server lives on. Uses `echogym/Faulty-v0`, registered by `echogym serve --fault-injection`
(observation ``[step in episode, env index over the server's life]``)."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from conftest import Server
from echogym import _native
from echogym.errors import ControlTimeoutError, NeedsResetError
from echogym.gym_vector import EchoVectorEnv


def test_a_stalled_step_times_out_and_a_panic_is_flagged(ipc, monkeypatch):
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
    keys = json.loads(panicky.spec_json)["info_keys"]
    panicky.reset()
    fields, _, _, truncated, info, _, _ = panicky.step(np.zeros((2, 1), np.float32))
    assert info[:, keys.index("env_error")].tolist() == [0.0, 1.0]
    assert truncated.tolist() == [False, True]
    assert fields[0][0].tolist() == [1.0, 1.0]
    panicky.reset()  # the failed env is reset; the lease lives
    panicky.close()
    stalled.close()
    del stalled, panicky, client
    assert server.stop() == 0


def _obs(envs: EchoVectorEnv) -> list[list[float]]:
    return envs.fields()["obs"].tolist()


def test_one_env_failing_in_a_vector_env_fails_alone(ipc):
    server = Server("pytest", ipc, "--fault-injection")
    actions = np.zeros((4, 1), np.float32)

    # Autoreset disabled: env 2 panics at its 3rd step.
    envs = EchoVectorEnv("echogym/Faulty-v0", 4, autostart=False, autoreset_mode="disabled",
                         panic_in="step", env_index=2, at_step=3)
    _, info = envs.reset()
    assert not info["env_error"].any()
    for step in (1, 2, 3):
        _, reward, terminated, truncated, info = envs.step(actions)
        want = [[float(step), float(i)] for i in range(4)]
        failed = [False] * 4
        if step == 3:
            want[2] = [0.0, 0.0]
            failed[2] = True
        assert _obs(envs) == want
        assert truncated.tolist() == failed
        assert info["env_error"].astype(bool).tolist() == failed
        assert not terminated.any() and not reward.any()
    with pytest.raises(NeedsResetError):
        envs.step(actions)
    _, info = envs.reset(options={"reset_mask": np.array([False, False, True, False])})
    assert _obs(envs)[2] == [0.0, 2.0]
    envs.step(actions)
    assert _obs(envs) == [[4.0, 0.0], [4.0, 1.0], [1.0, 2.0], [4.0, 3.0]]
    envs.close()

    # Same-step autoreset (the default): env 1 (env 5 over the server's life) panics at
    # its 2nd step, is restarted within that step, and the batch steps on untouched.
    envs = EchoVectorEnv("echogym/Faulty-v0", 4, autostart=False,
                         panic_in="step", env_index=5, at_step=2)
    envs.reset()
    envs.step(actions)
    _, _, _, truncated, info = envs.step(actions)
    assert truncated.tolist() == [False, True, False, False]
    assert info["env_error"].tolist() == [0.0, 1.0, 0.0, 0.0]
    assert info["_final_info"].tolist() == [False, True, False, False]
    assert info["final_info"][1]["env_error"] == 1.0
    assert info["final_obs"][1].tolist() == [0.0, 0.0]
    assert _obs(envs) == [[2.0, 4.0], [0.0, 5.0], [2.0, 6.0], [2.0, 7.0]]
    envs.step(actions)
    assert _obs(envs) == [[3.0, 4.0], [1.0, 5.0], [3.0, 6.0], [3.0, 7.0]]
    envs.close()

    status = server.status()
    assert status["env_errors"] == 2
    assert server.stop() == 0
