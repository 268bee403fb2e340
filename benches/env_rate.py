"""What the env benchmarks share: pinning a server's threads and timing a vector env."""

from __future__ import annotations

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
