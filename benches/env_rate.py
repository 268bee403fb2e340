"""What the env benchmarks share: pinning a server's threads and timing a vector env."""

from __future__ import annotations

import multiprocessing
import os
import time

import numpy as np

from echogym.gym_vector import EchoVectorEnv

# Mean `us_coupled` at the end of each timed run, by workload name (the image's workload).
COUPLED: dict[str, list[float]] = {}


def pin_process(pid: int, cpus: set[int]) -> None:
    """Pin every thread of a running process to `cpus` (threads started before do not
    inherit a later affinity change)."""
    for tid in os.listdir(f"/proc/{pid}/task"):
        os.sched_setaffinity(int(tid), cpus)


def env_steps_per_s(server: str, env_id: str, num_envs: int, config: dict, seconds: float,
                    name: str = "", scale: float = 0.3) -> float:
    """Step a batch with random actions for `seconds`; env-steps/s. With the ultrasound
    image, the mean `us_coupled` of the last step goes to COUPLED[name]."""
    envs = EchoVectorEnv(env_id, num_envs, server=server, **config)
    rng = np.random.default_rng(0)
    actions = [rng.uniform(-scale, scale, envs.action_space.shape).astype(np.float32)
               for _ in range(16)]
    envs.reset(seed=0)
    for k in range(5):
        envs.step(actions[k % 16])
    steps, started = 0, time.perf_counter()
    while time.perf_counter() - started < seconds:
        _, _, _, _, info = envs.step(actions[steps % 16])
        steps += 1
    elapsed = time.perf_counter() - started
    if "us_coupled" in info:
        COUPLED.setdefault(name, []).append(float(np.mean(info["us_coupled"])))
    envs.close()
    return steps * num_envs / elapsed


def _timed_client(server: str, env_id: str, num_envs: int, config: dict, start: float,
                  seconds: float, results) -> None:
    """One client of `env_steps_per_s_clients`: attach, warm up, then count the steps
    taken between `start` and `start + seconds` (time.time(), shared by all clients)."""
    envs = EchoVectorEnv(env_id, num_envs, server=server, **config)
    rng = np.random.default_rng(os.getpid())
    actions = [rng.uniform(-0.3, 0.3, envs.action_space.shape).astype(np.float32)
               for _ in range(16)]
    envs.reset(seed=os.getpid())
    steps = 0
    while time.time() < start:
        envs.step(actions[steps % 16])
        steps += 1
    steps, first = 0, time.time()
    while time.time() < start + seconds:
        envs.step(actions[steps % 16])
        steps += 1
    results.put((steps * num_envs, time.time() - first))
    envs.close()


def env_steps_per_s_clients(server: str, env_id: str, num_envs: int, config: dict,
                            seconds: float, clients: int, settle: float = 3.0) -> float:
    """`clients` processes, each stepping its own batch of `num_envs` (as a collector's
    workers do), all timed over the same window after `settle` s of attaching and warm-up;
    env-steps/s summed over the clients."""
    if clients == 1:
        return env_steps_per_s(server, env_id, num_envs, config, seconds)
    context = multiprocessing.get_context("spawn")
    results = context.Queue()
    start = time.time() + settle
    workers = [context.Process(target=_timed_client,
                               args=(server, env_id, num_envs, config, start, seconds, results))
               for _ in range(clients)]
    for worker in workers:
        worker.start()
    counted = [results.get(timeout=settle + seconds + 60) for _ in workers]
    for worker in workers:
        worker.join()
    if any(worker.exitcode for worker in workers):
        raise RuntimeError(f"a client failed: exit codes {[w.exitcode for w in workers]}")
    return sum(steps / elapsed for steps, elapsed in counted)
