"""``echogym view ENV_ID``: watch envs in the rerun viewer, live or saved to ``.rrd``.

Attaches to the running server (or starts a private one), leases ``--num-envs`` envs with
``render_mode="rerun"`` and steps them with a policy: ``scripted`` (UltrasoundScan's
force-controlled sweep, the demo's: hybrid force/motion controller, follow the target,
stay upright), ``random`` (uniform actions scaled by ``--action-scale``) or ``zero``.
Logged on the ``step`` and ``sim_time`` timelines: the arm links and probe (their
collision shapes), the torso's surface coloured by indentation, the contact point and
force arrow, F/T and the target force, reward terms, joint positions, the camera images
and the B-mode image (docs/viewer.md).

``--save FILE.rrd`` runs headless and writes the recording (open it later with ``rerun
FILE.rrd``); without it the rerun viewer is spawned (``--connect URL``: stream to a viewer
elsewhere, e.g. ``rerun --serve-grpc`` on your desktop).

``echogym view --calibration OUT`` shows a calibration report instead (``echogym calibrate
DATASET --out OUT``): every recording's measured, baseline and calibrated force, the
residuals and the worst mismatch spans (:mod:`echogym.apps.calibration_rerun`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import echogym
from echogym._native import resolve_spec
from echogym.apps.sweep_policy import scripted_action
from echogym.gym_vector import EchoVectorEnv
from echogym.rerun_recorder import RerunVectorRecorder

SCAN_ID = "echogym/UltrasoundScan-v0"
#: Logged frames per simulated second by default.
DEFAULT_LOG_RATE_HZ = 50.0


def env_config(env_id: str, policy: str, images: bool, extra: dict[str, Any]) -> dict[str, Any]:
    """The env config the viewer leases: cameras and the B-mode image for envs with a
    torso (``images``), the scripted sweep's controller, then ``extra`` on top."""
    config: dict[str, Any] = {}
    if images and env_id != "echogym/Null-v0":
        config["cameras"] = [
            {"name": "front", "width": 160, "height": 160, "depth": False, "shading": "smooth"},
            {"name": "probe", "width": 64, "height": 64, "rgb": False},
        ]
        if env_id != "echogym/PushCube-v0":
            config["ultrasound"] = {}
    if policy == "scripted":
        config["controller"] = {"kind": "hybrid_force_motion", "control_freq": 500.0}
    config.update(extra)
    return config


def policy_fn(policy: str, envs: EchoVectorEnv, scale: float, seed: int) -> Any:
    """A function from the observation batch to the action batch."""
    space = envs.single_action_space
    rng = np.random.default_rng(seed)
    if policy == "scripted":
        return scripted_action
    if policy == "zero":
        return lambda obs: np.zeros((envs.num_envs, *space.shape), np.float32)
    return lambda obs: (rng.uniform(space.low, space.high, (envs.num_envs, *space.shape))
                        * scale).astype(np.float32)


def prepare(env_id: str, policy: str, every: int | None, images: bool,
            extra: dict[str, Any]) -> tuple[dict[str, Any], int]:
    """The env config (scene state on, cameras rendering only logged frames) and the
    logging stride; ``ValueError`` when the env has no scene to show or the config is bad."""
    config = {**env_config(env_id, policy, images, extra), "scene_state": True}
    try:
        dt = json.loads(resolve_spec(env_id, json.dumps(config)))["dt_s"]
    except (echogym.InvalidConfigError, echogym.UnknownEnvError) as exc:
        raise ValueError(f"{env_id} cannot be viewed: {exc}") from exc
    if every is None:
        every = max(1, int(round(1.0 / (dt * DEFAULT_LOG_RATE_HZ))))
    if config.get("cameras"):
        config["cameras"] = [{"every": every, **cam} for cam in config["cameras"]]
    return config, every


def run(env_id: str, num_envs: int, steps: int, seed: int, server: str | None, policy: str,
        config: dict[str, Any], every: int, scale: float, recording: Any) -> dict[str, Any]:
    """Step the envs with logging on; timings and counts."""
    raw = EchoVectorEnv(env_id, num_envs, server=server, **config)
    try:
        envs = RerunVectorRecorder(raw, recording=recording, every=every)
        act = policy_fn(policy, raw, scale, seed)
        obs, _ = envs.reset(seed=seed)
        started = time.perf_counter()
        for _ in range(steps):
            obs, *_ = envs.step(act(obs))
        elapsed = time.perf_counter() - started
    finally:
        raw.close()
    dt = raw.echo_spec["dt_s"]
    return {"env_id": env_id, "num_envs": num_envs, "steps": steps, "every": every,
            "sim_seconds": steps * dt, "wall_s": elapsed,
            "env_steps_per_s": steps * num_envs / elapsed}


def open_recording(rr: Any, name: str, save: Path | None, connect: str | None) -> Any:
    """A recording stream saving to ``save``, streaming to ``connect``, or spawning the viewer."""
    recording = rr.RecordingStream("echogym", recording_id=f"{name}-{time.time_ns()}")
    if save is not None:
        save.parent.mkdir(parents=True, exist_ok=True)
        recording.save(save)
    elif connect is not None:
        recording.connect_grpc(connect)
    else:
        recording.spawn()
    return recording


def view_calibration(out: Path, save: Path | None, connect: str | None) -> int:
    """``--calibration OUT``: log the report's replays."""
    try:
        from echogym.apps.calibration_rerun import log_calibration
        from echogym.rerun_log import import_rerun

        rr = import_rerun()
        if not (out / "report.json").is_file():
            raise FileNotFoundError(f"{out / 'report.json'}: no calibration report there")
    except (ImportError, FileNotFoundError) as exc:
        print(f"echogym view: {exc}", file=sys.stderr)
        return 2
    recording = open_recording(rr, "calibration", save, connect)
    try:
        count = log_calibration(out, recording)
    finally:
        recording.disconnect()
    where = f"wrote {save}" if save is not None else "streamed to the viewer"
    print(f"{count} replays of {out}: {where}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="echogym view", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("env_id", nargs="?", help="an echogym physics env, e.g. echogym/UltrasoundScan-v0")
    parser.add_argument("--calibration", type=Path, default=None, metavar="OUT",
                        help="show the replays of `echogym calibrate ... --out OUT` instead of an env")
    parser.add_argument("--save", type=Path, default=None, help="write FILE.rrd instead of showing")
    parser.add_argument("--connect", default=None, metavar="URL",
                        help="stream to a running viewer (rerun+http://HOST:9876/proxy)")
    parser.add_argument("--steps", type=int, default=1000, help="env steps (default %(default)s)")
    parser.add_argument("--num-envs", type=int, default=1, help="envs, side by side (default 1)")
    parser.add_argument("--policy", choices=["scripted", "random", "zero"], default=None,
                        help="scripted sweep (UltrasoundScan's default), random (others') or zero")
    parser.add_argument("--action-scale", type=float, default=0.3,
                        help="random actions' share of the action range (default %(default)s)")
    parser.add_argument("--every", type=int, default=None,
                        help="log every N-th step (default: 50 frames per simulated second)")
    parser.add_argument("--no-images", action="store_true", help="no cameras or B-mode image")
    parser.add_argument("--config", type=json.loads, default={},
                        help="env config as JSON, e.g. '{\"robot\": \"ur5e\"}'")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--server", default=None,
                        help="server name (default $ECHOGYM_SERVER or 'default'; started if absent)")
    args = parser.parse_args(argv)
    if (args.env_id is None) == (args.calibration is None):
        parser.error("name an env, or a calibration report with --calibration OUT (one of them)")
    if args.calibration is not None:
        return view_calibration(args.calibration, args.save, args.connect)
    if args.steps < 1 or args.num_envs < 1:
        parser.error("--steps and --num-envs must be ≥ 1")
    if not isinstance(args.config, dict):
        parser.error("--config must be a JSON object")
    policy = args.policy or ("scripted" if args.env_id == SCAN_ID else "random")
    if policy == "scripted" and args.env_id != SCAN_ID:
        parser.error(f"--policy scripted is {SCAN_ID}'s sweep")
    try:
        from echogym.rerun_log import import_rerun

        rr = import_rerun()
        config, every = prepare(args.env_id, policy, args.every, not args.no_images, args.config)
    except (ImportError, ValueError) as exc:
        print(f"echogym view: {exc}", file=sys.stderr)
        return 2
    recording = open_recording(rr, args.env_id, args.save, args.connect)
    print(f"echogym {echogym.__version__}: viewing {args.env_id} x {args.num_envs}, {policy} policy, "
          f"{args.steps} steps")
    try:
        result = run(args.env_id, args.num_envs, args.steps, args.seed, args.server, policy, config,
                     every, args.action_scale, recording)
    finally:
        recording.disconnect()  # flush; a saved file gets its footer
    where = f"wrote {args.save}" if args.save is not None else "streamed to the viewer"
    print(f"{result['steps']} steps ({result['sim_seconds']:.2f} s simulated, logged every "
          f"{result['every']}): {result['env_steps_per_s']:,.0f} env-steps/s with logging; {where}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
