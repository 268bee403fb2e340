"""`benches/run envs`: echogym's physics envs against robosuite, side by side in one run.

echogym side: a private `echogym serve` pinned to ONE core (`taskset`, one worker thread),
driven from one Python process (gymnasium vector env over shared memory, random actions
of ±0.3, same-step autoreset, default randomization and breathing, episodes ending only at
the horizon like robosuite's `ignore_done`) pinned to the other core, so each figure is
env-steps/s per server core:
  (a) UltrasoundScan-v0, Panda, OSC_POSE, 20 Hz control (25 physics steps/step), 8 envs;
  (b) the same at 500 Hz control (1 physics step/step), batches of 16 envs;
  (c) (a) plus one 64×64 depth camera per env (`front`);
  (d) PushCube-v0 at 20 Hz, 8 envs (rigid cube, no torso), for reference;
  (e) UltrasoundScan-v0 at 20 Hz under the hybrid force/motion controller holding 5 N
      with zero motion actions (the probe stays on the skin, so every scan line is
      formed: the image's worst case), without and with the 128×128 `ultrasound` image
      (target: within 2× of the cost without; the mean `us_coupled` is reported).
The client side (benches/envs_client.py, skipped with `--no-client`): the async gain
(first-ready batches against the synchronous vector env, on this server) and the torchrl
collector ratio (on a separate 2-thread server, unpinned).
Imaging alone: `--ultrasound-json` (benches/ultrasound.rs, one core) gives images/s with
the probe coupled on the skin (every line formed), 128×128 and 256×256.
robosuite side (benches/envs_robosuite.py in benches/.venv-peers, one process, one core):
`Lift` Panda OSC_POSE at 20 Hz and UR5e OSC_POSE at 500 Hz.
Each figure is the median of `--repeats` runs of `--seconds`. Prints a markdown table,
writes benches/results/envs.{md,json}, and ends with one `RESULT key=value ...` line.
`--scaling`: benches/scaling.py's curve (batches of 16 and 64 at 1/2/4/8/16 server threads,
those the machine has cores for, one client and four; with `--env-step-bin`, the machine
alone) and its model.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

import echogym  # noqa: F401  (registers the envs)
import scaling
from bench_server import BenchServer, machine_description
from env_rate import COUPLED, env_steps_per_s, pin_process
from envs_client import async_gain, collector_ratio, table_lines

TARGETS = {"scan_20hz": 400.0, "scan_500hz_batch16": 8000.0, "scan_20hz_depth64": 200.0}
HYBRID_20HZ = {"kind": "hybrid_force_motion", "control_freq": 20.0}
SERVER_CPU, CLIENT_CPU = 1, 0

# Episodes end only at the horizon, like robosuite's `ignore_done=True` in the peer run;
# `scan_20hz_early_termination` shows the cost of the seed's early termination under
# random actions (an episode ends every few steps, each reset redraws and rebuilds the
# torso).
NO_EARLY_END = {"early_termination": False}
WORKLOADS = {
    "scan_20hz": ("echogym/UltrasoundScan-v0", 8,
                  {"controller": {"control_freq": 20.0}, "task": NO_EARLY_END}),
    "scan_500hz_batch16": ("echogym/UltrasoundScan-v0", 16, {"task": NO_EARLY_END}),
    "scan_20hz_depth64": (
        "echogym/UltrasoundScan-v0",
        8,
        {"controller": {"control_freq": 20.0}, "task": NO_EARLY_END,
         "cameras": [{"name": "front", "width": 64, "height": 64, "rgb": False}]},
    ),
    "scan_20hz_early_termination": ("echogym/UltrasoundScan-v0", 8,
                                    {"controller": {"control_freq": 20.0}}),
    "push_cube_20hz": ("echogym/PushCube-v0", 8, {}),
    "scan_20hz_hybrid": ("echogym/UltrasoundScan-v0", 8,
                         {"controller": HYBRID_20HZ, "task": NO_EARLY_END}),
    "scan_20hz_hybrid_ultrasound128": (
        "echogym/UltrasoundScan-v0", 8,
        {"controller": HYBRID_20HZ, "task": NO_EARLY_END, "ultrasound": {}}),
}
# Amplitude of the uniform random actions per workload (default 0.3); the hybrid
# workloads hold the probe on the skin.
ACTION_SCALE = {"scan_20hz_hybrid": 0.0, "scan_20hz_hybrid_ultrasound128": 0.0}
def robosuite(seconds: float, repeats: int) -> dict | None:
    """Run the robosuite side in its own virtualenv; None when unavailable."""
    python = os.path.join(os.path.dirname(__file__), ".venv-peers", "bin", "python")
    if not os.path.exists(python):
        return None
    out = subprocess.run(
        [python, os.path.join(os.path.dirname(__file__), "envs_robosuite.py"),
         "--seconds", str(seconds), "--repeats", str(repeats)],
        capture_output=True, text=True, check=True,
    )
    return json.loads(out.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-peers", action="store_true", help="skip robosuite")
    parser.add_argument("--ultrasound-json", help="output of the ultrasound imaging bench")
    parser.add_argument("--env-step-json", help="output of benches/env_step.rs (per-env cost)")
    parser.add_argument("--scaling", action="store_true",
                        help="also the scaling curve (benches/scaling.py)")
    parser.add_argument("--env-step-bin",
                        help="benches/env_step.rs's binary, for --scaling's machine-alone figures")
    parser.add_argument("--no-client", action="store_true",
                        help="skip the collector ratio and the async gain (envs_client.py)")
    args = parser.parse_args()
    os.sched_setaffinity(0, {CLIENT_CPU})

    runs: dict[str, list[float]] = {}
    with BenchServer("envs-bench", "--threads", "1") as server:
        pin_process(server.process.pid, {SERVER_CPU})
        for name, (env_id, n, config) in WORKLOADS.items():
            runs[name] = []
            for _ in range(args.repeats):
                runs[name].append(
                    env_steps_per_s(server.name, env_id, n, config, args.seconds, name,
                                    ACTION_SCALE.get(name, 0.3)))
                print(f"{name}: {runs[name][-1]:,.0f} env-steps/s", file=sys.stderr)
        gain = None if args.no_client else async_gain(server.name, args.seconds, args.repeats)
    env_step = None
    if args.env_step_json:
        with open(args.env_step_json) as f:
            env_step = json.load(f)
    scaling_lines, scaling_result = [], None
    if args.scaling:
        scaling_result = scaling.run(args.seconds, args.repeats, list(scaling.THREADS),
                                     list(scaling.BATCHES), args.env_step_bin,
                                     scaling.CLIENTS)
        scaling_lines = ["", "Scaling (benches/scaling.py):", "", *scaling.report(scaling_result)]
        os.sched_setaffinity(0, {CLIENT_CPU})
    os.sched_setaffinity(0, set(range(os.cpu_count() or 1)))
    collector = None
    if not args.no_client:
        with BenchServer("collector-bench", "--threads", "2") as collector_server:
            collector = collector_ratio(collector_server.name, args.seconds, args.repeats)
    peers = None if args.no_peers else robosuite(args.seconds, args.repeats)

    med = {k: statistics.median(v) for k, v in runs.items()}
    rows = [
        ("UltrasoundScan-v0 Panda OSC_POSE 20 Hz, 8 envs, no images", "scan_20hz"),
        ("UltrasoundScan-v0 Panda OSC_POSE 500 Hz, batch 16", "scan_500hz_batch16"),
        ("UltrasoundScan-v0 20 Hz + one 64×64 depth image", "scan_20hz_depth64"),
        ("UltrasoundScan-v0 20 Hz with the seed's early termination (resets every few steps)",
         "scan_20hz_early_termination"),
        ("PushCube-v0 Panda OSC_POSE 20 Hz, 8 envs", "push_cube_20hz"),
        ("UltrasoundScan-v0 hybrid force/motion 20 Hz holding 5 N, 8 envs, no images",
         "scan_20hz_hybrid"),
        ("the same + 128×128 `ultrasound` image", "scan_20hz_hybrid_ultrasound128"),
    ]
    lines = [
        f"Machine: {machine_description()}. echogym server pinned to 1 core (1 worker thread), "
        f"client on another; median of {args.repeats} × {args.seconds:g} s.",
        "",
        "| workload | env-steps/s per core | runs | target |",
        "|---|---:|---|---:|",
    ]
    for label, key in rows:
        target = TARGETS.get(key)
        verdict = "" if target is None else f"≥ {target:,.0f} ({'met' if med[key] >= target else 'MISSED'})"
        lines.append(f"| {label} | {med[key]:,.0f} | {', '.join(f'{r:,.0f}' for r in runs[key])} | {verdict} |")
    result = {"echogym": {k: {"median": med[k], "runs": v} for k, v in runs.items()}, "robosuite": peers}
    image_cost = med["scan_20hz_hybrid"] / med["scan_20hz_hybrid_ultrasound128"]
    coupled = statistics.median(COUPLED.get("scan_20hz_hybrid_ultrasound128", [float("nan")]))
    lines += [
        "",
        f"Ultrasound image at 20 Hz: the env costs {image_cost:.2f}× its cost without images "
        f"(target ≤ 2×; mean us_coupled at the end of the runs {coupled:.2f}).",
    ]
    result["ultrasound_cost_ratio"] = image_cost
    result["ultrasound_mean_coupled"] = coupled
    if args.ultrasound_json:
        with open(args.ultrasound_json) as f:
            imaging = json.load(f)
        result["imaging"] = imaging
        i128, i256 = imaging["images_per_s_128"], imaging["images_per_s_256"]
        lines.append(
            f"Imaging alone, one core, probe coupled (every line formed): 128×128 "
            f"{i128['median']:,.0f} images/s (runs {', '.join(f'{r:,.0f}' for r in i128['runs'])}; "
            f"target ≥ 500: {'met' if i128['median'] >= 500 else 'MISSED'}), 256×256 "
            f"{i256['median']:,.0f} images/s.")
    if peers:
        lift20 = peers["lift_panda_osc_20hz"]["median"]
        ur500 = peers["lift_ur5e_osc_500hz"]["median"]
        lines += [
            f"| robosuite {peers['robosuite_version']} Lift Panda OSC_POSE 20 Hz (MuJoCo "
            f"{peers['mujoco_version']}, 1 env) | {lift20:,.0f} | "
            f"{', '.join(f'{r:,.0f}' for r in peers['lift_panda_osc_20hz']['runs'])} | |",
            f"| robosuite Lift UR5e OSC_POSE 500 Hz (1 env) | {ur500:,.0f} | "
            f"{', '.join(f'{r:,.0f}' for r in peers['lift_ur5e_osc_500hz']['runs'])} | |",
            "",
            f"Ratios (same run): scan 20 Hz / Lift 20 Hz = {med['scan_20hz'] / lift20:.1f}× "
            f"(target ≥ 6×: {'met' if med['scan_20hz'] / lift20 >= 6 else 'MISSED'}); scan 500 Hz batch 16 / Lift UR5e 500 Hz = "
            f"{med['scan_500hz_batch16'] / ur500:.1f}×. robosuite reset (hard) "
            f"{peers['lift_reset_ms']['median']:.0f} ms.",
        ]
        result["ratio_scan20_vs_lift20"] = med["scan_20hz"] / lift20
        result["ratio_scan500_vs_lift_ur5e500"] = med["scan_500hz_batch16"] / ur500
    if env_step:
        lines.append(
            f"In-process (benches/env_step.rs, no transport, one core): UltrasoundScan-v0 20 Hz "
            f"{env_step['env_steps_per_s']['median']:,.0f} env-steps/s.")
        result["env_step"] = env_step
    lines += scaling_lines
    if scaling_result:
        result["scaling"] = scaling_result
    result["load_average"] = os.getloadavg()
    lines.append(f"Load average at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())}.")
    lines += table_lines(collector, gain)
    if collector is not None:
        result["collector"] = collector
    if gain is not None:
        result["async"] = gain
    table = "\n".join(lines)
    print(table)
    os.makedirs("benches/results", exist_ok=True)
    with open("benches/results/envs.md", "w") as f:
        f.write(table + "\n")
    with open("benches/results/envs.json", "w") as f:
        json.dump(result, f, indent=2)
    kv = " ".join(f"{k}={v:.0f}" for k, v in med.items())
    kv += f" ultrasound_cost_ratio={image_cost:.2f}"
    if args.ultrasound_json:
        kv += f" images_per_s_128={result['imaging']['images_per_s_128']['median']:.0f}"
    if peers:
        kv += f" ratio_vs_lift={result['ratio_scan20_vs_lift20']:.2f}"
    if scaling_result:
        kv += " " + scaling.result_kv(scaling_result)
    if collector is not None:
        kv += f" collector_ratio={collector['ratio']:.2f}"
    if gain is not None:
        kv += f" async_gain={gain['gain']:.2f}"
    print(f"RESULT {kv}")


if __name__ == "__main__":
    main()
