"""`benches/run viewer`: what watching costs — the viewer's logging, the scene-state fields
and the viewing camera — against plain stepping, in one run.

A private `echogym serve` pinned to ONE core (one worker thread) and the Python client
(gymnasium vector env, random actions of ±0.3, no early termination) pinned to the other,
like `benches/run envs`. UltrasoundScan-v0, Panda, OSC_POSE at 500 Hz, 8 envs:
  (a) plain stepping (logging off);
  (b) `scene_state=True` (the fields a viewer reads; nothing logged);
  (c) `RerunVectorRecorder` logging every env every step to an .rrd file (rerun's file
      sink, written by its own threads);
  (d) the same logging every 10th step (50 frames per simulated second, `echogym view`'s
      default);
  (e) `render_mode="rgb_array"`: the 256×256 smooth-shaded viewing camera every step;
  (f) the same with `render_camera={"every": 20}` (a 25 frames/s video).
Cost of one camera frame (1 env; step time with the camera minus without): 64×64 and
256×256, flat (observation) and smooth (viewing) shading.
`--baseline-bin PATH`: also (a) against another build of the server (e.g. the main
branch's, without the viewer), alternating fresh servers of both builds, so "logging off
costs nothing" is measured rather than argued.
Each figure is the median of `--repeats` runs of `--seconds`. Prints a markdown table,
writes benches/results/viewer.{md,json}, and ends with one `RESULT key=value ...` line.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time

import numpy as np

import echogym  # noqa: F401  (registers the envs)
from bench_server import BenchServer, machine_description
from env_rate import pin_process
from echogym.gym_vector import EchoVectorEnv
from echogym.rerun_recorder import RerunVectorRecorder

SERVER_CPU, CLIENT_CPU = 1, 0
SCAN = "echogym/UltrasoundScan-v0"
BASE = {"task": {"early_termination": False}}
NUM_ENVS = 8


def steps_per_s(server: str, num_envs: int, config: dict, seconds: float,
                log_every: int | None = None) -> float:
    """Env-steps/s of random ±0.3 actions for `seconds` (`log_every`: with rerun logging
    to a file)."""
    raw = EchoVectorEnv(SCAN, num_envs, server=server, **BASE, **config)
    envs, recording, folder = raw, None, None
    if log_every is not None:
        import rerun as rr

        folder = tempfile.TemporaryDirectory()
        recording = rr.RecordingStream("echogym-bench")
        recording.save(os.path.join(folder.name, "bench.rrd"))
        envs = RerunVectorRecorder(raw, recording=recording, every=log_every)
    rng = np.random.default_rng(0)
    actions = [rng.uniform(-0.3, 0.3, raw.action_space.shape).astype(np.float32) for _ in range(16)]
    envs.reset(seed=0)
    for k in range(5):
        envs.step(actions[k % 16])
    steps, started = 0, time.perf_counter()
    while time.perf_counter() - started < seconds:
        envs.step(actions[steps % 16])
        steps += 1
    if recording is not None:
        recording.disconnect()  # the file written is part of the cost
    elapsed = time.perf_counter() - started
    raw.close()
    if folder is not None:
        folder.cleanup()
    return steps * num_envs / elapsed


def off_with_binary(binary: str | None, name: str, seconds: float) -> float:
    """Plain stepping against a fresh server of `binary` (None: this checkout's)."""
    previous = os.environ.get("ECHOGYM_BIN")
    if binary:
        os.environ["ECHOGYM_BIN"] = binary
    try:
        with BenchServer(name, "--threads", "1") as server:
            pin_process(server.process.pid, {SERVER_CPU})
            return steps_per_s(server.name, NUM_ENVS, {}, seconds)
    finally:
        if previous is None:
            os.environ.pop("ECHOGYM_BIN", None)
        else:
            os.environ["ECHOGYM_BIN"] = previous


WORKLOADS = {
    "off": ("plain stepping (logging off)", {}, None),
    "scene_state": ("`scene_state=True` (fields only)", {"scene_state": True}, None),
    "rerun_every_step": ("rerun logging, every step", {"scene_state": True}, 1),
    "rerun_every_10": ("rerun logging, every 10th step (`echogym view`'s 50 Hz)",
                       {"scene_state": True}, 10),
    "rgb_array": ("`render_mode=\"rgb_array\"` (256×256 smooth, every step)",
                  {"render_mode": "rgb_array"}, None),
    "rgb_array_every_20": ("`rgb_array` with `render_camera={\"every\": 20}` (25 frames/s)",
                           {"render_mode": "rgb_array", "render_camera": {"every": 20}}, None),
}
CAMERAS = {f"{shading}_{size}": {"name": "v", "preset": "overview", "width": size, "height": size,
                                 "depth": False, "shading": shading}
           for size in (64, 256) for shading in ("flat", "smooth")}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--baseline-bin", default=None,
                        help="an `echogym` binary to compare plain stepping against")
    args = parser.parse_args()
    os.sched_setaffinity(0, {CLIENT_CPU})
    runs: dict[str, list[float]] = {name: [] for name in [*WORKLOADS, "one_env", *CAMERAS]}
    with BenchServer("viewer-bench", "--threads", "1") as server:
        pin_process(server.process.pid, {SERVER_CPU})
        # Interleave the workloads so a neighbour's load spreads over all of them.
        for _ in range(args.repeats):
            for name, (_, config, every) in WORKLOADS.items():
                runs[name].append(steps_per_s(server.name, NUM_ENVS, config, args.seconds, every))
                print(f"{name}: {runs[name][-1]:,.0f} env-steps/s", file=sys.stderr)
            runs["one_env"].append(steps_per_s(server.name, 1, {}, args.seconds))
            for name, camera in CAMERAS.items():
                runs[name].append(steps_per_s(server.name, 1, {"cameras": [camera]}, args.seconds))
                print(f"camera {name}: {runs[name][-1]:,.0f} steps/s", file=sys.stderr)
    # After the shared server is gone: each run starts its own (one ipc location).
    if args.baseline_bin:
        runs["off_this_build"], runs["off_baseline"] = [], []
        for r in range(args.repeats):
            for key, binary in (("off_baseline", args.baseline_bin),
                                ("off_this_build", os.environ.get("ECHOGYM_BIN"))):
                runs[key].append(off_with_binary(binary, f"viewer-ab{r}{key}", args.seconds))
                print(f"{key}: {runs[key][-1]:,.0f} env-steps/s", file=sys.stderr)
    os.sched_setaffinity(0, set(range(os.cpu_count() or 1)))
    med = {k: statistics.median(v) for k, v in runs.items()}
    lines = [
        f"Machine: {machine_description()}. Server pinned to 1 core (1 worker thread), client "
        f"on another; UltrasoundScan-v0 Panda OSC_POSE 500 Hz, {NUM_ENVS} envs, random ±0.3 "
        f"actions; median of {args.repeats} × {args.seconds:g} s.",
        "",
        "| workload | env-steps/s | vs off | runs |",
        "|---|---:|---:|---|",
    ]
    for name, (label, _, _) in WORKLOADS.items():
        lines.append(f"| {label} | {med[name]:,.0f} | {med[name] / med['off']:.2f}× | "
                     f"{', '.join(f'{r:,.0f}' for r in runs[name])} |")
    if args.baseline_bin:
        lines.append(f"| plain stepping, this build (fresh servers, alternating) | "
                     f"{med['off_this_build']:,.0f} | {med['off_this_build'] / med['off_baseline']:.2f}× "
                     f"baseline | {', '.join(f'{r:,.0f}' for r in runs['off_this_build'])} |")
        lines.append(f"| plain stepping, baseline build `{args.baseline_bin}` | "
                     f"{med['off_baseline']:,.0f} | 1.00× baseline | "
                     f"{', '.join(f'{r:,.0f}' for r in runs['off_baseline'])} |")
    base_ms = 1e3 / med["one_env"]
    frame_ms = {name: max(0.0, 1e3 / med[name] - base_ms) for name in CAMERAS}
    lines += ["", "| camera frame (1 env) | ms per frame |", "|---|---:|"]
    for name in CAMERAS:
        shading, size = name.split("_")
        lines.append(f"| {size}×{size} {shading} | {frame_ms[name]:.2f} |")
    table = "\n".join(lines)
    print(table)
    out = os.path.join(os.path.dirname(__file__), "results")
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, "viewer.md"), "w") as f:
        f.write(table + "\n")
    with open(os.path.join(out, "viewer.json"), "w") as f:
        json.dump({"runs": runs, "median": med, "frame_ms": frame_ms}, f, indent=2)
    print("RESULT " + " ".join(
        [f"{k}={med[k] / med['off']:.3f}" for k in WORKLOADS if k != "off"]
        + [f"off_env_steps_per_s={med['off']:.0f}"]
        + [f"frame_ms_{k}={v:.2f}" for k, v in frame_ms.items()]))


if __name__ == "__main__":
    main()
