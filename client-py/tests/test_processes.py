"""Many real client processes against one real server: interleaved attach/step/detach
with every observation checked, a client killed with SIGKILL mid-step (its lease is
reclaimed within 2 s, others carry on), a server stopped or killed under running clients
(typed `ServerStoppedError`, never a hang), restart after kill -9, auto-started private
servers that go away with their process, and owner-only shared memory."""

import os
import stat
import subprocess
import sys
import textwrap
import threading
import time

import gymnasium as gym
import numpy as np
import pytest

import echogym
from conftest import Server, run_python

CLIENT = textwrap.dedent(
    """
    import sys, numpy as np, gymnasium as gym, echogym
    tag = int(sys.argv[1])
    rng = np.random.default_rng(tag)
    for round in range(3):
        k = 1 + (tag + round) % 6
        envs = gym.make_vec("echogym/Null-v0", num_envs=k,
                            vectorization_mode="vector_entry_point", max_episode_steps=None)
        envs.reset(seed=tag)
        for step in range(1, 151):
            a = rng.uniform(-1, 1, (k, 7)).astype(np.float32)
            obs, *_ = envs.step(a)
            assert (obs[:, 1:8] == a).all(), (tag, round, step)
            assert (obs[:, 0] == step).all(), (tag, round, step)
        envs.close()
    print("ok")
    """
)


def test_eight_processes_interleaved_keep_data_intact(server):
    procs = [
        subprocess.Popen([sys.executable, "-c", CLIENT, str(i)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for i in range(8)
    ]
    for proc in procs:
        out, err = proc.communicate(timeout=180)
        assert proc.returncode == 0, err
        assert out.strip() == "ok"
    assert server.status()["leases"] == []


FOREVER = textwrap.dedent(
    """
    import numpy as np, gymnasium as gym, echogym
    envs = gym.make_vec("echogym/Null-v0", num_envs=4, vectorization_mode="vector_entry_point")
    envs.reset()
    print("attached", flush=True)
    a = np.zeros((4, 7), np.float32)
    while True:
        envs.step(a)
    """
)


def test_killed_client_lease_is_reclaimed_and_others_carry_on(server):
    child = subprocess.Popen([sys.executable, "-c", FOREVER], stdout=subprocess.PIPE, text=True)
    assert child.stdout.readline().strip() == "attached"
    envs = gym.make_vec("echogym/Null-v0", num_envs=2, vectorization_mode="vector_entry_point")
    envs.reset()
    assert len(server.status()["leases"]) == 2
    time.sleep(0.1)
    child.kill()
    child.wait()
    killed = time.monotonic()
    while len(server.status()["leases"]) > 1:
        envs.step(np.zeros((2, 7), np.float32))
        assert time.monotonic() - killed < 2.0, "lease not reclaimed within 2 s"
        time.sleep(0.01)
    assert server.status()["reclaimed_leases"] == 1
    obs, *_ = envs.step(np.full((2, 7), 0.5, np.float32))
    assert (obs[:, 1] == 0.5).all()
    envs.close()


def test_server_sigterm_under_a_stepping_client_raises_server_stopped(server):
    envs = gym.make_vec("echogym/Null-v0", num_envs=4, vectorization_mode="vector_entry_point")
    envs.reset()
    errors = []

    def run():
        try:
            while True:
                envs.step(np.zeros((4, 7), np.float32))
        except echogym.EchogymError as e:
            errors.append(e)

    thread = threading.Thread(target=run)
    thread.start()
    time.sleep(0.2)
    assert server.stop() == 0
    thread.join(timeout=10)
    assert not thread.is_alive(), "client hung after the server stopped"
    assert isinstance(errors[0], echogym.ServerStoppedError)
    with pytest.raises(echogym.ServerStoppedError):
        envs.step(np.zeros((4, 7), np.float32))
    with pytest.raises(echogym.ServerNotRunningError):
        echogym.connect()
    envs.close()


def test_server_kill9_then_restart(server, ipc):
    envs = gym.make_vec("echogym/Null-v0", num_envs=2, vectorization_mode="vector_entry_point")
    envs.reset()
    server.kill()
    with pytest.raises(echogym.ServerStoppedError):
        envs.step(np.zeros((2, 7), np.float32))
    envs.close()
    del envs
    again = Server("pytest", ipc)
    try:
        envs = gym.make_vec("echogym/Null-v0", num_envs=2, vectorization_mode="vector_entry_point")
        envs.reset()
        obs, *_ = envs.step(np.full((2, 7), 0.25, np.float32))
        assert (obs[:, 1] == 0.25).all()
        envs.close()
    finally:
        assert again.stop() == 0


def test_autostarted_private_server_goes_away_with_its_process(ipc):
    result = run_python(
        textwrap.dedent(
            """
            import gymnasium as gym, numpy as np, echogym
            env = gym.make("echogym/Null-v0")
            env.reset(seed=0)
            env.step(np.zeros(7, np.float32))
            print(echogym.connect().status()["pid"])
            """
        )
    )
    assert result.returncode == 0, result.stderr
    pid = int(result.stdout.strip().splitlines()[-1])
    deadline = time.monotonic() + 10
    while os.path.exists(f"/proc/{pid}") and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not os.path.exists(f"/proc/{pid}"), "private server outlived its process"


def test_shared_memory_is_owner_only(server, ipc):
    envs = gym.make_vec("echogym/Null-v0", num_envs=2, vectorization_mode="vector_entry_point")
    envs.reset()
    segments = [n for n in os.listdir("/dev/shm") if n.startswith(ipc.prefix)]
    assert len(segments) > 5
    for name in segments:
        mode = stat.S_IMODE(os.stat(f"/dev/shm/{name}").st_mode)
        assert mode & 0o077 == 0, f"{name} has mode {mode:o}"
    assert stat.S_IMODE(os.stat(ipc.root).st_mode) & 0o077 == 0
    envs.close()
