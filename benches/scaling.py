"""`benches/run scaling` (and `benches/run envs --scaling`): env-steps/s against server threads.

`UltrasoundScan-v0` at 20 Hz (the envs suite's headline workload), one batch of 16, 64 or 256
envs (`--batches`), stepped by one Python client (gymnasium vector env over shared memory), at
1/2/4/8/16 server threads (`--threads`; those the machine has cores for). While N is below the core
count the server's threads are pinned to N cores of their own (distinct physical cores
first where the CPU has SMT) and the client to another; at N = all cores they share.
`Null-v0` at 1 thread gives the serial part δ.

With `--clients 1,4` (the default), also K client processes, each stepping its own batch
(as a torchrl collector's workers or SB3's subprocesses do): while one client's batch is
published and its Python runs, the workers step another's, so the pool is not idle between
batches. The clients get cores of their own while server threads and clients fit, else the
server's threads keep cores of their own and the clients share the rest.

With `--env-step-bin` (benches/env_step.rs, which `benches/run scaling` builds), the machine
alone: N processes, one per core, each stepping 4 envs in-process (no server): h(N), the
per-core speed at N busy cores over one busy core (shared caches, memory bandwidth, clocks,
a VM's neighbours), measured, since no 2-core figure predicts it.

The model (docs/benchmarks.md, "Scaling model"): one env step costs c on a worker thread and
δ serially (dispatcher, shared-memory publish, client), the cores run at h(N) of one core's
speed, so rate(N) = 1/(c/(N·h(N)) + δ), with c and δ from the 1-thread figures (h = 1 where
not measured). What the model leaves out is the server's own loss: a batch ends with its
slowest thread, and the client shares a core at N = all cores.
Writes benches/results/scaling.{md,json} (or `--out NAME`) and ends with one `RESULT` line.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

import echogym  # noqa: F401  (registers the envs)
from bench_server import BenchServer, machine_description
from env_rate import env_steps_per_s, env_steps_per_s_clients, pin_process

SCAN_20HZ = {"controller": {"control_freq": 20.0}, "task": {"early_termination": False}}
BATCHES = (16, 64)
THREADS = (1, 2, 4, 8, 16)
CLIENTS = (1, 4)


def numbers(text: str) -> list[int]:
    return [int(x) for x in text.split(",") if x]


def cores_in_order() -> list[int]:
    """The CPUs this process may use, one per physical core first, then SMT siblings."""
    allowed = sorted(os.sched_getaffinity(0))
    first, siblings = [], []
    seen: set[str] = set()
    for cpu in allowed:
        try:
            with open(f"/sys/devices/system/cpu/cpu{cpu}/topology/thread_siblings_list") as f:
                core = f.read().strip()
        except OSError:
            core = str(cpu)
        (siblings if core in seen else first).append(cpu)
        seen.add(core)
    return first + siblings


def placement(threads: int, cpus: list[int], clients: int = 1) -> tuple[set[int], set[int]]:
    """(server CPUs, client CPUs): own cores for each while they fit; the server's threads
    on cores of their own while they fit, the clients on the rest; else all shared."""
    if threads + clients <= len(cpus):
        return set(cpus[clients:clients + threads]), set(cpus[:clients])
    if threads < len(cpus):
        return set(cpus[len(cpus) - threads:]), set(cpus[:len(cpus) - threads])
    return set(cpus), set(cpus)


def machine_alone(env_step_bin: str, seconds: float, counts: list[int]) -> dict[int, float]:
    """Total env-steps/s of N in-process env loops (4 envs each), one per core."""
    cpus = cores_in_order()
    totals = {}
    for n in counts:
        loops = [subprocess.Popen(["taskset", "-c", str(cpu), env_step_bin, "--envs", "4",
                                   "--seconds", str(seconds), "--repeats", "1"],
                                  stdout=subprocess.PIPE, text=True) for cpu in cpus[:n]]
        totals[n] = sum(json.loads(loop.communicate()[0])["env_steps_per_s"]["median"]
                        for loop in loops)
        print(f"machine alone, {n} cores: {totals[n]:,.0f} env-steps/s", file=sys.stderr)
    return totals


def measure(seconds: float, repeats: int, thread_counts: list[int], batches: list[int],
            alone: dict[int, float] | None = None, client_counts: tuple[int, ...] = (1,)) -> dict:
    cpus = cores_in_order()
    runs: dict[int, dict[int, list[float]]] = {}
    clients_runs: dict[int, dict[tuple[int, int], list[float]]] = {}
    null: dict[int, list[float]] = {}
    for threads in thread_counts:
        runs[threads], clients_runs[threads] = {}, {}
        for clients in client_counts:
            server_cpus, client_cpus = placement(threads, cpus, clients)
            os.sched_setaffinity(0, client_cpus)
            with BenchServer(f"scaling-{threads}-{clients}", "--threads", str(threads)) as server:
                pin_process(server.process.pid, server_cpus)
                for batch in batches:
                    rates = [env_steps_per_s_clients(server.name, "echogym/UltrasoundScan-v0",
                                                     batch, SCAN_20HZ, seconds, clients)
                             for _ in range(repeats)]
                    print(f"scaling {threads} threads, {clients} clients, batch {batch}: "
                          f"{[round(r) for r in rates]}", file=sys.stderr)
                    if clients > 1:
                        clients_runs[threads][(batch, clients)] = rates
                        continue
                    runs[threads][batch] = rates
                    if threads != 1:
                        continue
                    # The dispatcher, transport and client alone: a batch of Null-v0 envs.
                    null[batch] = [env_steps_per_s(server.name, "echogym/Null-v0", batch, {},
                                                   seconds) for _ in range(repeats)]
    os.sched_setaffinity(0, set(cpus))
    result: dict = {"machine": machine_description(), "cpus_in_order": cpus,
                    "seconds": seconds, "repeats": repeats, "batches": {}}
    h = {n: 1.0 for n in thread_counts}
    if alone:
        h = {n: alone[n] / (n * alone[1]) for n in thread_counts}
        result["machine_alone"] = {"env_steps_per_s": alone, "per_core_speed": h}
    for batch in batches:
        med = {n: statistics.median(runs[n][batch]) for n in thread_counts}
        delta = 1.0 / statistics.median(null[batch])
        c = max(1.0 / med[1] - delta, 0.0)
        predicted = {n: 1.0 / (c / (n * h[n]) + delta) for n in thread_counts}
        result["batches"][batch] = {
            "runs": {n: runs[n][batch] for n in thread_counts},
            "median": med,
            "efficiency": {n: med[n] / (n * med[1]) for n in thread_counts},
            "null_runs": null[batch],
            "model": {"per_env_step_s": c, "serial_per_env_step_s": delta,
                      "predicted": predicted,
                      "efficiency": {n: predicted[n] / (n * predicted[1]) for n in thread_counts}},
        }
    result["clients"] = {}
    for batch in batches:
        for clients in client_counts:
            if clients == 1:
                continue
            med = {n: statistics.median(clients_runs[n][(batch, clients)])
                   for n in thread_counts}
            result["clients"][f"{batch}x{clients}"] = {
                "batch": batch, "clients": clients,
                "runs": {n: clients_runs[n][(batch, clients)] for n in thread_counts},
                "median": med,
                "efficiency": {n: med[n] / (n * med[1]) for n in thread_counts},
            }
    return result


def run(seconds: float, repeats: int, threads: list[int], batches: list[int],
        env_step_bin: str | None, clients: tuple[int, ...] = (1,)) -> dict:
    """`measure` at the thread counts this machine has cores for (1 always), with the
    machine alone when `env_step_bin` is given."""
    cores = len(os.sched_getaffinity(0))
    threads = sorted({1, *(n for n in threads if n <= cores)})
    alone = machine_alone(env_step_bin, seconds, threads) if env_step_bin else None
    return measure(seconds, repeats, threads, batches, alone, tuple(sorted({1, *clients})))


def report(result: dict) -> list[str]:
    alone = result.get("machine_alone")
    lines = [
        f"Machine: {result['machine']}. `UltrasoundScan-v0` Panda OSC_POSE 20 Hz, one Python "
        f"client; server threads on cores of their own while N < cores (client on another), "
        f"all shared at N = cores; median of {result['repeats']} × {result['seconds']:g} s.",
        "",
        "| batch | threads | env-steps/s | runs | efficiency | model | model's efficiency |",
        "|---:|---:|---:|---|---:|---:|---:|",
    ]
    if alone:
        lines[0:0] = [
            "The machine alone (N in-process loops of 4 envs, one per core, no server): "
            + ", ".join(f"{n} cores {r:,.0f} env-steps/s (per-core speed h = "
                        f"{alone['per_core_speed'][n]:.2f})"
                        for n, r in alone["env_steps_per_s"].items()) + ".", ""]
    for batch, b in result["batches"].items():
        for n, rate in b["median"].items():
            runs = ", ".join(f"{r:,.0f}" for r in b["runs"][n])
            lines.append(f"| {batch} | {n} | {rate:,.0f} | {runs} | {b['efficiency'][n]:.2f} | "
                         f"{b['model']['predicted'][n]:,.0f} | {b['model']['efficiency'][n]:.3f} |")
    if result.get("clients"):
        lines += ["", "Several clients, each stepping its own batch (efficiency against the same "
                  "clients at 1 thread):", "",
                  "| batch × clients | threads | env-steps/s | runs | efficiency |",
                  "|---:|---:|---:|---|---:|"]
        for key, b in result["clients"].items():
            for n, rate in b["median"].items():
                runs = ", ".join(f"{r:,.0f}" for r in b["runs"][n])
                lines.append(f"| {b['batch']} × {b['clients']} | {n} | {rate:,.0f} | {runs} | "
                             f"{b['efficiency'][n]:.2f} |")
    for batch, b in result["batches"].items():
        m = b["model"]
        lines.append(
            f"\nBatch {batch}: c = {m['per_env_step_s'] * 1e6:,.0f} µs per env step at 1 thread, "
            f"δ = {m['serial_per_env_step_s'] * 1e6:.2f} µs (Null-v0, runs "
            f"{', '.join(f'{r:,.0f}' for r in b['null_runs'])} env-steps/s).")
    return lines


def result_kv(result: dict) -> str:
    """`scaling_{B}_{N}t=` and `scaling_{B}_eff{N}=` for each batch B and thread count N
    (`scaling_{B}x{K}_...` with K clients), `machine_h{N}=` where the machine alone was
    measured."""
    kv = [f"machine_h{n}={h:.2f}"
          for n, h in result.get("machine_alone", {}).get("per_core_speed", {}).items() if n > 1]
    for batch, b in result["batches"].items():
        for n, rate in b["median"].items():
            kv.append(f"scaling_{batch}_{n}t={rate:.0f}")
        for n, eff in b["efficiency"].items():
            if n > 1:
                kv.append(f"scaling_{batch}_eff{n}={eff:.2f}")
    for key, b in result.get("clients", {}).items():
        for n, rate in b["median"].items():
            kv.append(f"scaling_{key}_{n}t={rate:.0f}")
        for n, eff in b["efficiency"].items():
            if n > 1:
                kv.append(f"scaling_{key}_eff{n}={eff:.2f}")
    return " ".join(kv)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=numbers, default=list(THREADS),
                        help="server thread counts, comma-separated; 1 is always measured "
                             "(the model's base), counts above the cores are skipped")
    parser.add_argument("--batches", type=numbers, default=list(BATCHES),
                        help="batch sizes, comma-separated")
    parser.add_argument("--clients", type=numbers, default=list(CLIENTS),
                        help="client process counts, comma-separated (each steps its own "
                             "batch); 1 is always measured")
    parser.add_argument("--env-step-bin",
                        help="benches/env_step.rs's binary: also measure the machine alone")
    parser.add_argument("--out", default="benches/results/scaling",
                        help="path of the results without extension (.md and .json are written)")
    args = parser.parse_args()
    result = run(args.seconds, args.repeats, args.threads, args.batches, args.env_step_bin,
                 args.clients)
    lines = report(result)
    print("\n".join(lines))
    os.makedirs(os.path.dirname(args.out) or ".", exist_ok=True)
    with open(args.out + ".md", "w") as f:
        f.write("\n".join(lines) + "\n")
    with open(args.out + ".json", "w") as f:
        json.dump(result, f, indent=2)
    print(f"RESULT {result_kv(result)}")


if __name__ == "__main__":
    main()
