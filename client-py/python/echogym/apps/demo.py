"""``echogym demo``: a force-controlled ultrasound sweep on parallel envs.

Starts (or joins) an echogym server, leases ``--num-envs`` ``echogym/UltrasoundScan-v0``
envs with the hybrid force/motion controller (force along the probe axis held at 5 N by
the controller, motion in the skin's plane from the policy), and drives them with a
scripted policy over shared memory: follow the moving target point on the torso and keep
the probe upright. The torso breathes and its stiffness, damping and placement are
randomized per env.

Shows a progress bar on a terminal (tqdm on stderr; nothing when redirected), then prints
force tracking (share of the in-contact time within ±1 N of
the target), sweep completion and env-steps/s; writes ``force.png`` (contact force vs
time against the target), ``frames.png`` (camera frames and the probe's B-mode
ultrasound image, from a twin of env 0), ``demo.mp4`` (env 0's sweep seen by a
smooth-shaded viewing camera, 25 frames/s) and ``summary.json`` to
``--out``. Exit code 0 when the sweep met the ±1 N / 80 % criterion, else 1.

The figures need matplotlib (``pip install 'echogym[plots]'``), the video moviepy
(``pip install 'echogym[video]'``).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from pathlib import Path

import numpy as np

import echogym
from echogym._progress import progress_bar
from echogym.apps.plotting import plots_available, pyplot
from echogym.apps.sweep_policy import scripted_action
from echogym.gym_vector import EchoVectorEnv
from echogym.video import VIDEO_EXTRA, write_mp4

ENV_ID = "echogym/UltrasoundScan-v0"
#: Frames per second of demo.mp4.
VIDEO_FPS = 25


def run(num_envs: int, horizon: int, seed: int, server: str | None, robot: str,
        camera_size: int, progress: bool = True, video_size: int = 256) -> dict:
    """Run one sweep episode on every env; the traces and figures as a dict."""
    client = echogym.connect(server, autostart=True)
    common = dict(server=client.name, robot=robot, horizon=horizon,
                  controller={"kind": "hybrid_force_motion", "control_freq": 500.0})
    envs = EchoVectorEnv(ENV_ID, num_envs, **common)
    # A twin of env 0 (same config and seed, so the same episode) with cameras: frames
    # for the figure without rendering every env.
    cameras = [
        {"name": "front", "width": camera_size, "height": camera_size, "depth": False},
        {"name": "side", "width": camera_size, "height": camera_size, "depth": False},
        {"name": "probe", "width": camera_size, "height": camera_size, "rgb": False},
    ]
    # The video camera renders only the steps that become frames.
    video_every = max(1, round(1.0 / (VIDEO_FPS * envs.echo_spec["dt_s"])))
    if video_size > 0:
        cameras.append({"name": "video", "preset": "overview", "width": video_size,
                        "height": video_size, "depth": False, "shading": "smooth",
                        "every": video_every})
    viewer = EchoVectorEnv(ENV_ID, 1, cameras=cameras, ultrasound={}, **common)
    dt = envs.echo_spec["dt_s"]
    keys = envs.echo_spec["info_keys"]
    obs, info = envs.reset(seed=seed)
    view, _ = viewer.reset(seed=seed)
    video = [np.array(view["video_rgb"][0])] if video_size > 0 else []
    force = np.full((horizon, num_envs), np.nan)
    contact = np.zeros((horizon, num_envs), bool)
    progress_at_end = np.zeros(num_envs)
    ended = np.zeros(num_envs, bool)
    termination = np.zeros(num_envs)
    frames: list[tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
    frame_steps = set(np.linspace(0, horizon - 1, 4).astype(int))
    bar = progress_bar(horizon, enabled=progress, unit="step")
    started = time.perf_counter()
    for step in range(horizon):
        action = scripted_action(obs)
        obs, reward, terminated, truncated, info = envs.step(action)
        view, *_ = viewer.step(action[:1])
        if video_size > 0 and (step + 1) % video_every == 0:
            video.append(np.array(view["video_rgb"][0]))
        live = ~ended
        # With same-step autoreset, an ended env's info is in `final_info`.
        source = {k: np.array(info[k]) for k in keys}
        for i in np.flatnonzero(terminated | truncated):
            for k in keys:
                source[k][i] = info["final_info"][i][k]
        force[step, live] = source["contact_force"][live]
        contact[step, live] = source["in_contact"][live] > 0.5
        done = (terminated | truncated) & live
        progress_at_end[done] = source["progress"][done]
        termination[done] = source["termination"][done]
        ended |= done
        if step in frame_steps:
            frames.append((step * dt, np.array(view["front_rgb"][0]), np.array(view["side_rgb"][0]),
                           np.array(view["probe_depth"][0]), np.array(view["ultrasound"][0])))
        bar.update(1)
        if step % 25 == 0:
            bar.set_postfix_str(f"{(step + 1) * num_envs / (time.perf_counter() - started):,.0f} env-steps/s",
                                refresh=False)
    elapsed = time.perf_counter() - started
    bar.close()
    envs.close()
    viewer.close()
    in_contact = contact.sum()
    within = (contact & (np.abs(force - 5.0) <= 1.0)).sum()
    return {
        "num_envs": num_envs,
        "horizon": horizon,
        "dt_s": dt,
        "seed": seed,
        "robot": robot,
        "env_steps_per_s": horizon * num_envs / elapsed,
        "wall_s": elapsed,
        "in_contact_share": float(in_contact / contact.size),
        "within_1n_share_of_contact": float(within / max(in_contact, 1)),
        "mean_abs_force_error_n": float(np.nanmean(np.abs(force[contact] - 5.0))) if in_contact else None,
        "sweep_completion": progress_at_end.tolist(),
        "early_terminations": int((termination > 0).sum()),
        "_force": force,
        "_contact": contact,
        "_frames": frames,
        "_video": video,
        "video_fps": 1.0 / (video_every * dt),
    }


def write_figures(result: dict, out: Path) -> list[Path]:
    """force.png and frames.png; the paths written."""
    plt = pyplot()
    out.mkdir(parents=True, exist_ok=True)
    force, contact, dt = result["_force"], result["_contact"], result["dt_s"]
    t = np.arange(force.shape[0]) * dt
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.axhspan(4.0, 6.0, color="tab:green", alpha=0.15, label="target ±1 N")
    ax.axhline(5.0, color="tab:green", lw=1.5, label="target 5 N")
    for k in range(force.shape[1]):
        ax.plot(t, np.where(contact[:, k], force[:, k], np.nan), lw=0.8, alpha=0.8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("contact force along the probe axis [N]")
    ax.set_title(f"{ENV_ID}, {force.shape[1]} envs, scripted hybrid force/motion sweep "
                 f"({result['within_1n_share_of_contact']:.0%} of contact time within ±1 N)",
                 fontsize=9)
    ax.set_ylim(0, 10)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    force_png = out / "force.png"
    fig.savefig(force_png, dpi=120)
    plt.close(fig)

    frames = result["_frames"]
    fig, axes = plt.subplots(4, len(frames), figsize=(2.4 * len(frames), 10.4),
                             gridspec_kw={"height_ratios": [1, 1, 1, 1.4]})
    for k, (time_s, front, side, depth, ultrasound) in enumerate(frames):
        axes[0, k].imshow(front)
        axes[0, k].set_title(f"front, t = {time_s:.2f} s", fontsize=8)
        axes[1, k].imshow(side)
        axes[1, k].set_title("side", fontsize=8)
        axes[2, k].imshow(depth, cmap="viridis_r", vmin=0.0, vmax=0.2)
        axes[2, k].set_title("probe camera, depth 0-0.2 m", fontsize=8)
        # 40 mm aperture × 120 mm depth (the defaults), drawn to scale.
        axes[3, k].imshow(ultrasound, cmap="gray", vmin=0, vmax=255, extent=[-20, 20, 120, 0])
        axes[3, k].set_title("ultrasound (B-mode)", fontsize=8)
        for a in axes[:, k]:
            a.axis("off")
    fig.tight_layout()
    frames_png = out / "frames.png"
    fig.savefig(frames_png, dpi=120)
    plt.close(fig)
    return [force_png, frames_png]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="echogym demo", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--num-envs", type=int, default=8, help="parallel envs (default %(default)s)")
    parser.add_argument("--horizon", type=int, default=2500,
                        help="steps at 500 Hz control (default %(default)s = 5 s, 10 cm of sweep)")
    parser.add_argument("--robot", choices=["panda", "ur5e"], default="panda")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--camera-size", type=int, default=64, help="camera width/height [px]")
    parser.add_argument("--video-size", type=int, default=256,
                        help="demo.mp4 width/height [px] (0: no video; default %(default)s)")
    parser.add_argument("--out", type=Path, default=Path("demo-output"), help="output folder")
    parser.add_argument("--server", default=None,
                        help="server name (default $ECHOGYM_SERVER or 'default'; started if absent)")
    args = parser.parse_args(argv)
    if not plots_available("demo"):
        return 2
    if args.video_size > 0 and importlib.util.find_spec("moviepy") is None:
        print(f"echogym demo: demo.mp4 needs moviepy: {VIDEO_EXTRA} (or --video-size 0)",
              file=sys.stderr)
        return 2

    print(f"echogym {echogym.__version__}: {ENV_ID} x {args.num_envs}, {args.robot}, "
          f"hybrid force/motion, scripted sweep, {args.horizon} steps at 500 Hz")
    result = run(args.num_envs, args.horizon, args.seed, args.server, args.robot, args.camera_size,
                 video_size=args.video_size)
    paths = write_figures(result, args.out)
    if result["_video"]:
        paths.append(write_mp4(result["_video"], args.out / "demo.mp4", result["video_fps"]))
    summary = {k: v for k, v in result.items() if not k.startswith("_")}
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    ok = summary["within_1n_share_of_contact"] >= 0.8
    completion = np.array(summary["sweep_completion"])
    print(f"force tracking: {summary['within_1n_share_of_contact']:.1%} of in-contact time within "
          f"±1 N of 5 N (target ≥ 80%: {'met' if ok else 'MISSED'}); mean |error| "
          f"{summary['mean_abs_force_error_n']:.2f} N; in contact {summary['in_contact_share']:.0%} "
          f"of the time")
    print(f"sweep completion: mean {completion.mean():.0%}, {int((completion >= 1).sum())}/"
          f"{len(completion)} envs finished the path, {summary['early_terminations']} early "
          f"terminations")
    print(f"throughput: {summary['env_steps_per_s']:,.0f} env-steps/s "
          f"({args.num_envs} envs stepped from Python with the policy in the loop, plus a "
          f"camera twin; {summary['wall_s']:.1f} s)")
    print("wrote " + ", ".join(str(p) for p in [*paths, args.out / "summary.json"]))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
