"""`benches/run transport`: the shared-memory path against gymnasium's AsyncVectorEnv.

Measured in one run, side by side, on whatever machine runs it:
  (a) Python round trip of one `step` for one Null env (p50 / p99 / p99.9);
  (b) aggregate env-steps/s for a Null batch of 64 from one Python process and from 2;
  (c) the same 64-env workload through `gymnasium.vector.AsyncVectorEnv` (with and
      without `shared_memory=True`) over an equivalent pure-Python null env.
Each figure is the median of `--repeats` runs. Prints a markdown table, writes it to
benches/results/transport.md, and ends with one `RESULT key=value ...` line.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import textwrap
import time

import gymnasium as gym
import numpy as np

import echogym  # noqa: F401  (registers the envs)
from bench_server import BenchServer, machine_description

TARGETS = {"p50_us": 10.0, "p99_us": 60.0, "batch64_steps_per_s": 1_000_000, "ratio_vs_async": 20.0}


class PyNullEnv(gym.Env):
    """Pure-Python twin of echogym/Null-v0: obs[0] counts steps, obs[1:8] echo the action."""

    observation_space = gym.spaces.Box(-np.inf, np.inf, (64,), np.float32)
    action_space = gym.spaces.Box(-1, 1, (7,), np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.t = 0
        return np.zeros(64, np.float32), {}

    def step(self, action):
        self.t += 1
        obs = np.zeros(64, np.float32)
        obs[0] = self.t
        obs[1:8] = action
        return obs, float(action[0]), False, self.t >= 1000, {}


def latency(steps: int) -> tuple[float, float, float]:
    envs = gym.make_vec("echogym/Null-v0", num_envs=1, vectorization_mode="vector_entry_point")
    envs.reset(seed=0)
    action = np.zeros((1, 7), np.float32)
    for _ in range(2000):
        envs.step(action)
    samples = np.empty(steps)
    clock = time.perf_counter_ns
    for i in range(steps):
        t = clock()
        envs.step(action)
        samples[i] = clock() - t
    envs.close()
    p50, p99, p999 = np.percentile(samples / 1000.0, [50, 99, 99.9])
    return float(p50), float(p99), float(p999)


THROUGHPUT = textwrap.dedent(
    """
    import sys, time, numpy as np, gymnasium as gym, echogym
    seconds = float(sys.argv[1])
    envs = gym.make_vec("echogym/Null-v0", num_envs=64, vectorization_mode="vector_entry_point")
    envs.reset(seed=0)
    a = np.zeros((64, 7), np.float32)
    for _ in range(500):
        envs.step(a)
    n, t0 = 0, time.perf_counter()
    while (dt := time.perf_counter() - t0) < seconds:
        for _ in range(200):
            envs.step(a)
        n += 200
    envs.close()
    print(n * 64 / dt)
    """
)


def throughput(processes: int, seconds: float) -> float:
    procs = [
        subprocess.Popen([sys.executable, "-c", THROUGHPUT, str(seconds)], stdout=subprocess.PIPE, text=True)
        for _ in range(processes)
    ]
    return sum(float(p.communicate()[0].strip().splitlines()[-1]) for p in procs)


def async_vector(shared_memory: bool, seconds: float) -> float:
    envs = gym.vector.AsyncVectorEnv([PyNullEnv] * 64, shared_memory=shared_memory)
    envs.reset(seed=0)
    a = np.zeros((64, 7), np.float32)
    for _ in range(20):
        envs.step(a)
    n, t0 = 0, time.perf_counter()
    while (dt := time.perf_counter() - t0) < seconds:
        envs.step(a)
        n += 1
    envs.close()
    return n * 64 / dt


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=2.0, help="per throughput run")
    parser.add_argument("--latency-steps", type=int, default=50_000)
    args = parser.parse_args()

    with BenchServer("bench-transport"):
        lat = [latency(args.latency_steps) for _ in range(args.repeats)]
        one = [throughput(1, args.seconds) for _ in range(args.repeats)]
        two = [throughput(2, args.seconds) for _ in range(args.repeats)]
    shm = [async_vector(True, args.seconds) for _ in range(args.repeats)]
    plain = [async_vector(False, args.seconds) for _ in range(args.repeats)]

    med = statistics.median
    p50, p99, p999 = (med(x[i] for x in lat) for i in range(3))
    r = {
        "p50_us": p50,
        "p99_us": p99,
        "p999_us": p999,
        "batch64_steps_per_s": med(one),
        "batch64_2proc_steps_per_s": med(two),
        "async_shm_steps_per_s": med(shm),
        "async_steps_per_s": med(plain),
    }
    r["ratio_vs_async"] = r["batch64_steps_per_s"] / max(r["async_shm_steps_per_s"], r["async_steps_per_s"])

    def ok(key, higher=True):
        target = TARGETS[key]
        met = r[key] >= target if higher else r[key] <= target
        return "met" if met else "**missed**"

    lines = [
        f"### Transport benchmark ({time.strftime('%Y-%m-%d')}, {machine_description()})",
        "",
        f"Median of {args.repeats} runs; throughput runs last {args.seconds:.0f} s each.",
        "",
        "| measure | echogym | target | |",
        "|---|---:|---:|---|",
        f"| (a) step round trip, 1 Null env, p50 | {p50:.1f} µs | ≤ 10 µs | {ok('p50_us', False)} |",
        f"| (a) step round trip, 1 Null env, p99 | {p99:.1f} µs | ≤ 60 µs | {ok('p99_us', False)} |",
        f"| (a) step round trip, 1 Null env, p99.9 | {p999:.1f} µs | | |",
        f"| (a) p99 over the {args.repeats} runs (min–max) | {min(x[1] for x in lat):.1f}–{max(x[1] for x in lat):.1f} µs | | |",
        f"| (b) Null batch 64, 1 process | {r['batch64_steps_per_s']:,.0f} env-steps/s | ≥ 1,000,000 | {ok('batch64_steps_per_s')} |",
        f"| (b) Null batch 64, 2 processes (sum) | {r['batch64_2proc_steps_per_s']:,.0f} env-steps/s | | |",
        f"| (c) AsyncVectorEnv, 64 py-null envs, shared_memory=True | {r['async_shm_steps_per_s']:,.0f} env-steps/s | | |",
        f"| (c) AsyncVectorEnv, 64 py-null envs, shared_memory=False | {r['async_steps_per_s']:,.0f} env-steps/s | | |",
        f"| echogym batch 64 / best AsyncVectorEnv | {r['ratio_vs_async']:,.0f}× | ≥ 20× | {ok('ratio_vs_async')} |",
        "",
    ]
    table = "\n".join(lines)
    print(table)
    os.makedirs(os.path.join(os.path.dirname(__file__), "results"), exist_ok=True)
    with open(os.path.join(os.path.dirname(__file__), "results", "transport.md"), "w") as f:
        f.write(table)
    with open(os.path.join(os.path.dirname(__file__), "results", "transport.json"), "w") as f:
        json.dump({"machine": machine_description(), "python": platform.python_version(), **r}, f, indent=1)
    print("RESULT " + " ".join(f"{k}={v:.4g}" for k, v in r.items()))


if __name__ == "__main__":
    main()
