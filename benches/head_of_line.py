"""Head-of-line: bystanders' step latency while another client steps a big batch.

Two bystanders step one exchange every `--interval-ms` (as an actor computing a policy
between steps would): a *small* one (one `Null-v0` env, in this process; its exchange
runs inline on the dispatcher) and a *medium* one (`--medium-envs` (4)
`UltrasoundScan-v0` envs, in a process of its own; ≈ 0.4 ms an exchange, above the
dispatcher's 100 µs inline budget, so it runs off the dispatcher). First alone
("solo"), then while another client process attaches `--envs` (64) `UltrasoundScan-v0`
envs, resets them and steps them back to back ("loaded": from the big lease's first step
on; its attach, reset and detach (with the big process's exit) are reported apart).

Each variant is a fresh server, one after the other in the same run: by default "no
lane" (`--lane-budget-us=0`: every exchange above the inline budget queues FIFO on the
worker pool, the code before the medium lane) and "lane" (the default server: a medium
exchange runs on the medium lane while a big one is on the pool). Reports each
bystander's p50 / p99 / max step latency per phase, the big batch's mean exchange time,
and issue 15's criterion per bystander: loaded p99 within 2× solo p99 and no step slower
than 20 ms. Prints a markdown table, writes it under benches/results/, ends with a
`RESULT` line.

    benches/run hol [--seconds S] [--envs N] [--medium-envs M] [--interval-ms MS]
                    [--big-config JSON] [--variants no-lane,lane] [--serve-arg=FLAG]
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

#: Phases, shared with the child processes through `phase`.
WARMUP, SOLO, ATTACH, RESET, LOADED, DETACH, DONE = range(7)
NAMES = {SOLO: "solo", ATTACH: "attach", RESET: "reset", LOADED: "loaded", DETACH: "detach"}
PHASES = ("solo", "attach", "reset", "loaded", "detach")

#: The server arguments of each variant.
VARIANTS = {"no-lane": ["--lane-budget-us=0"], "lane": []}


def big_client(server: str, num_envs: int, config: dict, phase: mp.Value, stop: mp.Event,
               out: mp.Queue) -> None:
    """Attach `num_envs` scan envs, reset, then step until told to stop."""
    client = echogym.connect(server)
    phase.value = ATTACH
    lease = client.attach("echogym/UltrasoundScan-v0", num_envs, config, "same_step")
    phase.value = RESET
    lease.reset()
    width = json.loads(lease.spec_json)["action"]["size"]
    actions = np.zeros((num_envs, width), dtype=np.float32)
    phase.value = LOADED
    exchanges, started = 0, time.perf_counter()
    while not stop.is_set():
        lease.step(actions)
        exchanges += 1
    out.put((exchanges, time.perf_counter() - started))
    lease.close()


def medium_bystander(server: str, num_envs: int, interval: float, phase: mp.Value,
                     ready: mp.Event, out: mp.Queue) -> None:
    """Step `num_envs` scan envs every `interval` until the phase is DONE; latencies by
    phase."""
    client = echogym.connect(server)
    lease = client.attach("echogym/UltrasoundScan-v0", num_envs, {}, "same_step")
    lease.reset()
    width = json.loads(lease.spec_json)["action"]["size"]
    actions = np.zeros((num_envs, width), dtype=np.float32)
    ready.set()
    lat: dict[int, list[float]] = {}
    while (current := phase.value) != DONE:
        t0 = time.perf_counter_ns()
        lease.step(actions)
        lat.setdefault(current, []).append((time.perf_counter_ns() - t0) / 1e3)
        time.sleep(interval)
    out.put({NAMES[k]: v for k, v in lat.items() if k in NAMES})
    lease.close()


def step_small(lease, action: np.ndarray, seconds: float, interval: float, phase: mp.Value,
               lat: dict[str, list[float]]) -> None:
    """Step `lease` for `seconds`, adding latencies [µs] under the current phase's name."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        current = phase.value
        t0 = time.perf_counter_ns()
        lease.step(action)
        if current in NAMES:
            lat.setdefault(NAMES[current], []).append((time.perf_counter_ns() - t0) / 1e3)
        time.sleep(interval)


def stats(values: list[float]) -> tuple[float, float, float, int]:
    a = np.asarray(values)
    return float(np.percentile(a, 50)), float(np.percentile(a, 99)), float(a.max()), len(a)


def criterion(lat: dict[str, list[float]]) -> bool:
    solo, loaded = stats(lat["solo"]), stats(lat["loaded"])
    return loaded[1] <= 2 * solo[1] and loaded[2] <= 20_000


def run_variant(args, serve_args: list[str]) -> dict:
    """One server: both bystanders solo, then beside the big batch."""
    interval = args.interval_ms / 1e3
    with BenchServer("hol", *serve_args) as server:
        ctx = mp.get_context("spawn")
        phase, stop, out = ctx.Value("i", WARMUP), ctx.Event(), ctx.Queue()
        medium = None
        if args.medium_envs > 0:
            ready, medium_out = ctx.Event(), ctx.Queue()
            medium = ctx.Process(target=medium_bystander, args=(
                server.name, args.medium_envs, interval, phase, ready, medium_out))
            medium.start()
            if not ready.wait(120):
                raise RuntimeError("the medium bystander did not start")
        client = echogym.connect(server.name)
        small = client.attach("echogym/Null-v0", 1, {}, "same_step")
        small.reset()
        action = np.zeros((1, json.loads(small.spec_json)["action"]["size"]), np.float32)
        small_lat: dict[str, list[float]] = {}
        step_small(small, action, 1.0, interval, phase, small_lat)  # warm-up
        phase.value = SOLO
        step_small(small, action, args.seconds, interval, phase, small_lat)

        big = ctx.Process(target=big_client, args=(
            server.name, args.envs, json.loads(args.big_config), phase, stop, out))
        big.start()
        # Until the big lease steps, then `seconds` of it.
        while phase.value < LOADED and big.is_alive():
            step_small(small, action, 0.05, interval, phase, small_lat)
        step_small(small, action, args.seconds, interval, phase, small_lat)
        # How many of the medium lease's exchanges ran on the medium lane.
        lane_share = "—"
        for lease in client.status()["leases"]:
            if lease["env_id"].endswith("UltrasoundScan-v0") and lease["num_envs"] == args.medium_envs:
                lane_share = f"{lease.get('lane_exchanges', 0)} of {lease['exchanges']}"
        # The big client stops, detaches and exits (the bystanders keep stepping).
        phase.value = DETACH
        stop.set()
        while big.is_alive():
            step_small(small, action, 0.05, interval, phase, small_lat)
        exchanges, elapsed = out.get(timeout=120)
        big.join(timeout=60)
        phase.value = DONE
        medium_lat = medium_out.get(timeout=60) if medium else {}
        if medium:
            medium.join(timeout=60)
        small.close()
    return {"small": small_lat, "medium": medium_lat,
            "big_ms": elapsed / max(exchanges, 1) * 1e3, "big_exchanges": exchanges,
            "lane_share": lane_share}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="per phase")
    parser.add_argument("--envs", type=int, default=64)
    parser.add_argument("--medium-envs", type=int, default=4,
                        help="scan envs of the medium bystander (0: none)")
    parser.add_argument("--interval-ms", type=float, default=1.0)
    parser.add_argument("--big-config", default="{}", help="config of the big batch's envs (JSON)")
    parser.add_argument("--variants", default="no-lane,lane",
                        help=f"comma-separated, run in this order: {', '.join(VARIANTS)}")
    parser.add_argument("--out", default="benches/results/head_of_line.md")
    parser.add_argument("--serve-arg", action="append", default=[],
                        help="extra `echogym serve` argument (repeatable), e.g. --serve-arg=--worker-nice=0")
    args = parser.parse_args()
    variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown or not variants:
        parser.error(f"unknown variant(s) {unknown}; known: {', '.join(VARIANTS)}")

    results = {v: run_variant(args, [*args.serve_arg, *VARIANTS[v]]) for v in variants}

    bystanders = [("small", "Null-v0 × 1")]
    if args.medium_envs > 0:
        bystanders.append(("medium", f"UltrasoundScan-v0 × {args.medium_envs}"))
    header = " | ".join(variants)
    lines = [
        f"| head of line ({args.envs} × UltrasoundScan-v0 {args.big_config}) "
        f"p50 / p99 / max [µs] (steps) | {header} |",
        "|---|" + "---|" * len(variants),
    ]
    fmt = lambda s: f"{s[0]:.0f} / {s[1]:.0f} / {s[2]:.0f} ({s[3]})"  # noqa: E731
    for key, label in bystanders:
        for phase in PHASES:
            cells = [fmt(stats(results[v][key][phase])) if phase in results[v][key] else "—"
                     for v in variants]
            lines.append(f"| {label}: {phase} | {' | '.join(cells)} |")
        cells = ["pass" if criterion(results[v][key]) else "FAIL" for v in variants]
        lines.append(f"| {label}: loaded p99 ≤ 2 × solo p99, max ≤ 20 ms | {' | '.join(cells)} |")
    if args.medium_envs > 0:
        cells = [results[v]["lane_share"] for v in variants]
        lines.append(f"| medium bystander's exchanges on the medium lane | {' | '.join(cells)} |")
    cells = [f"{results[v]['big_ms']:.1f} ms ({results[v]['big_exchanges']})" for v in variants]
    lines.append(f"| big batch exchange, mean | {' | '.join(cells)} |")
    lines += [
        "",
        f"Machine: {machine_description()}; bystander interval {args.interval_ms} ms, "
        f"{args.seconds:g} s per phase; variants run one after the other: "
        + ", ".join(f"{v} ({' '.join(VARIANTS[v]) or 'default server'})" for v in variants)
        + f"; extra serve arguments: {' '.join(args.serve_arg) or 'none'}.",
    ]
    table = "\n".join(lines)
    print(table)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(table + "\n")
    fields = []
    for v in variants:
        tag = v.replace("-", "_")
        for key, _ in bystanders:
            for phase in ("solo", "loaded"):
                p50, p99, mx, _ = stats(results[v][key][phase])
                fields.append(f"{tag}_{key}_{phase}_p50_us={p50:.0f} {tag}_{key}_{phase}_p99_us={p99:.0f} "
                              f"{tag}_{key}_{phase}_max_us={mx:.0f}")
            fields.append(f"{tag}_{key}_pass={int(criterion(results[v][key]))}")
        fields.append(f"{tag}_big_exchange_ms={results[v]['big_ms']:.1f}")
    print("RESULT " + " ".join(fields))
    return 0


if __name__ == "__main__":
    sys.exit(main())
