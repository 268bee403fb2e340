"""``python -m echogym.demo``: drive a batch of envs through a server and report throughput.

Connects to the server named ``--server`` (starting a private one if none runs), leases
``--num-envs`` envs, steps them with random actions for ``--seconds`` and prints
env-steps/s and the step round-trip latency of a single env.
"""

from __future__ import annotations

import argparse
import sys
import time

import gymnasium as gym
import numpy as np

import echogym


def _bar(fraction: float, width: int = 30) -> str:
    filled = int(fraction * width)
    return "[" + "#" * filled + "." * (width - filled) + "]"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m echogym.demo", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="echogym/Null-v0", help="env id (default %(default)s)")
    parser.add_argument("--num-envs", type=int, default=64, help="batch size (default %(default)s)")
    parser.add_argument("--seconds", type=float, default=5.0, help="run time (default %(default)s)")
    parser.add_argument("--server", default=None, help="server name (default $ECHOGYM_SERVER or 'default')")
    args = parser.parse_args(argv)

    client = echogym.connect(args.server, autostart=True)
    status = client.status()
    print(f"echogym {echogym.__version__}: server {status['name']!r} (pid {status['pid']}, "
          f"{status['threads']} worker threads)")
    envs = gym.make_vec(args.env, num_envs=args.num_envs, vectorization_mode="vector_entry_point",
                        server=client.name)
    rng = np.random.default_rng(0)
    envs.reset(seed=0)
    actions = rng.uniform(-1, 1, envs.action_space.shape).astype(np.float32)
    steps, started, last_print = 0, time.perf_counter(), 0.0
    while (elapsed := time.perf_counter() - started) < args.seconds:
        for _ in range(100):
            envs.step(actions)
        steps += 100
        if elapsed - last_print > 0.25:
            last_print = elapsed
            rate = steps * args.num_envs / elapsed
            sys.stdout.write(f"\r{_bar(elapsed / args.seconds)} {rate:12,.0f} env-steps/s")
            sys.stdout.flush()
    elapsed = time.perf_counter() - started
    envs.close()
    print(f"\r{_bar(1.0)} {steps * args.num_envs / elapsed:12,.0f} env-steps/s "
          f"({args.num_envs} envs x {steps:,} batch steps in {elapsed:.1f} s)")

    single = gym.make_vec(args.env, num_envs=1, vectorization_mode="vector_entry_point",
                          server=client.name)
    single.reset(seed=0)
    one = np.zeros((1, single.action_space.shape[1]), np.float32)
    samples = []
    for _ in range(20_000):
        t = time.perf_counter_ns()
        single.step(one)
        samples.append(time.perf_counter_ns() - t)
    single.close()
    p50, p99 = np.percentile(np.array(samples) / 1000.0, [50, 99])
    print(f"single-env step round trip: p50 {p50:.1f} µs, p99 {p99:.1f} µs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
