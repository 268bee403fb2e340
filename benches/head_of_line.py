"""Head-of-line: a bystander's step latency while another client steps a big batch.

A bystander steps one `Null-v0` env (one step every `--interval-ms`, as an actor
computing a policy between steps would), first alone ("solo"), then while another client
process attaches `--envs` (64) `UltrasoundScan-v0` envs, resets them and steps them back
to back ("loaded": from the big lease's first step on; its attach and reset are reported
apart). Reports the bystander's p50 / p99 / max step latency per phase, the big batch's
mean exchange time, and issue 15's criterion: loaded p99 within 2× solo p99 and no step
slower than 20 ms. Prints a markdown table, writes it under benches/results/, ends with a
`RESULT` line.

    benches/run hol [--seconds S] [--envs N] [--interval-ms MS] [--big-config JSON]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_server import BenchServer, machine_description  # noqa: E402

import echogym  # noqa: E402


def big_client(server: str, num_envs: int, config: dict, phase: mp.Value, stop: mp.Event,
               out: mp.Queue) -> None:
    """Attach `num_envs` scan envs, reset, then step until told to stop."""
    client = echogym.connect(server)
    phase.value = 1  # attaching
    lease = client.attach("echogym/UltrasoundScan-v0", num_envs, config, "same_step")
    phase.value = 2  # resetting
    lease.reset()
    width = json.loads(lease.spec_json)["action"]["size"]
    actions = np.zeros((num_envs, width), dtype=np.float32)
    phase.value = 3  # stepping
    exchanges, started = 0, time.perf_counter()
    while not stop.is_set():
        lease.step(actions)
        exchanges += 1
    out.put((exchanges, time.perf_counter() - started))
    lease.close()


def step_for(lease, action: np.ndarray, seconds: float, interval: float, label=None) -> dict:
    """Step `lease` for `seconds`; latencies [µs] by phase label (`label()` or "solo")."""
    lat: dict[str, list[float]] = {}
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        key = label() if label else "solo"
        t0 = time.perf_counter_ns()
        lease.step(action)
        lat.setdefault(key, []).append((time.perf_counter_ns() - t0) / 1e3)
        if interval > 0:
            time.sleep(interval)
    return lat


def stats(values: list[float]) -> tuple[float, float, float, int]:
    a = np.asarray(values)
    return float(np.percentile(a, 50)), float(np.percentile(a, 99)), float(a.max()), len(a)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="per phase")
    parser.add_argument("--envs", type=int, default=64)
    parser.add_argument("--interval-ms", type=float, default=1.0)
    parser.add_argument("--big-config", default="{}", help="config of the big batch's envs (JSON)")
    parser.add_argument("--out", default="benches/results/head_of_line.md")
    parser.add_argument("--serve-arg", action="append", default=[],
                        help="extra `echogym serve` argument (repeatable), e.g. --serve-arg=--worker-nice=0")
    args = parser.parse_args()
    interval = args.interval_ms / 1e3

    with BenchServer("hol", *args.serve_arg) as server:
        client = echogym.connect(server.name)
        bystander = client.attach("echogym/Null-v0", 1, {}, "same_step")
        bystander.reset()
        action = np.zeros((1, json.loads(bystander.spec_json)["action"]["size"]), np.float32)
        step_for(bystander, action, 1.0, interval)  # warm-up
        lat = step_for(bystander, action, args.seconds, interval)

        ctx = mp.get_context("spawn")
        phase, stop, out = ctx.Value("i", 0), ctx.Event(), ctx.Queue()
        big = ctx.Process(target=big_client, args=(server.name, args.envs, json.loads(args.big_config), phase, stop, out))
        big.start()
        names = {0: "starting", 1: "attach", 2: "reset", 3: "loaded"}
        label = lambda: names[phase.value]  # noqa: E731
        # Until the big lease steps, then `seconds` of it.
        while phase.value < 3 and big.is_alive():
            for key, values in step_for(bystander, action, 0.05, interval, label).items():
                lat.setdefault(key, []).extend(values)
        for key, values in step_for(bystander, action, args.seconds, interval, label).items():
            lat.setdefault(key, []).extend(values)
        stop.set()
        exchanges, elapsed = out.get(timeout=120)
        big.join(timeout=60)
        bystander.close()

    solo, loaded = stats(lat["solo"]), stats(lat["loaded"])
    passed = loaded[1] <= 2 * solo[1] and loaded[2] <= 20_000
    rows = [(f"bystander {key}", stats(lat[key])) for key in ("solo", "attach", "reset", "loaded") if key in lat]
    big_ms = elapsed / max(exchanges, 1) * 1e3
    lines = [
        f"| head of line ({args.envs} × UltrasoundScan-v0 {args.big_config} beside a Null-v0 bystander) "
        "| p50 / p99 / max [µs] | steps |",
        "|---|---|---|",
        *(f"| {name} | {p50:.0f} / {p99:.0f} / {mx:.0f} | {n} |" for name, (p50, p99, mx, n) in rows),
        f"| big batch exchange (mean) | {big_ms:.1f} ms | {exchanges} |",
        f"| criterion: loaded p99 ≤ 2 × solo p99, max ≤ 20 ms | {'pass' if passed else 'FAIL'} | |",
        "",
        f"Machine: {machine_description()}; bystander interval {args.interval_ms} ms, "
        f"{args.seconds:.0f} s per phase; serve arguments: {' '.join(args.serve_arg) or 'none'}.",
    ]
    table = "\n".join(lines)
    print(table)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(table + "\n")
    print(
        f"RESULT solo_p50_us={solo[0]:.0f} solo_p99_us={solo[1]:.0f} solo_max_us={solo[2]:.0f} "
        f"loaded_p50_us={loaded[0]:.0f} loaded_p99_us={loaded[1]:.0f} loaded_max_us={loaded[2]:.0f} "
        f"big_exchange_ms={big_ms:.1f} pass={int(passed)}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
