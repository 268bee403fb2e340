"""``echogym ultrasound``: look at the synthetic B-mode image through real envs.

Starts (or joins) an echogym server and writes to ``--out``:

- ``sweep.png`` and ``sweep.gif``: the probe swept along the torso's midline (head-ward,
  ``echogym/UltrasoundScan-v0`` with a fixed trajectory, the hybrid force/motion
  controller holding 5 N and the demo's scripted policy), frames with time, contact
  force and coupling;
- ``press.png``: the probe over the kidney (site ``lower_left`` of
  ``echogym/CalibrationPress-v0``) in air, then held at increasing depth: the image
  appears on contact and the deep anatomy rises as the tissue compresses;
- ``sites.png``: the seed's five sites pressed 6 mm: ribs and their shadows at the head
  end, the vertebra on the midline, the kidney and liver.

Every image is the env's ``ultrasound`` observation (uint8, rows = depth from the face,
columns = scan lines along the array) delivered over shared memory. The figures need
matplotlib (``pip install 'echogym[plots]'``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

import echogym
from echogym.apps.plotting import plots_available, pyplot
from echogym.apps.sweep_policy import scripted_action
from echogym.gym_vector import EchoVectorEnv

SCAN_ID = "echogym/UltrasoundScan-v0"
PRESS_ID = "echogym/CalibrationPress-v0"
SITES = ["upper_left", "upper_right", "center", "lower_left", "lower_right"]


def press_image(server: str, site: str, depth_m: float | None, seed: int,
                ultrasound: dict) -> dict:
    """The image held at `depth_m` below the rest surface at `site` (None: at the start,
    in air), with the contact force and coupling then."""
    env = EchoVectorEnv(PRESS_ID, 1, server=server, ultrasound=ultrasound,
                        task={"site": site, "press_depth": depth_m or 0.002, "hold_time": 0.5})
    try:
        keys = env.echo_spec["info_keys"]
        dt = env.echo_spec["dt_s"]
        obs, info = env.reset(seed=seed)
        held = 0.0
        if depth_m is not None:
            zero = np.zeros(env.action_space.shape, np.float32)
            for _ in range(20_000):
                obs, _, terminated, truncated, info = env.step(zero)
                if terminated[0] or truncated[0]:
                    raise RuntimeError(f"the press at {site} ended before its hold")
                if info["phase"][0] == 1.0:
                    held += dt
                    if held >= 0.3:
                        break
        return {
            "image": np.array(obs["ultrasound"][0]),
            "force_n": float(info["contact_force"][0]),
            "depth_mm": None if depth_m is None else 1000.0 * float(info["depth"][0]),
            "coupled": float(info["us_coupled"][0]),
            "quality": float(info["us_quality"][0]),
            "info_keys": keys,
        }
    finally:
        env.close()


def sweep(server: str, seed: int, horizon: int, every: int, ultrasound: dict) -> list[dict]:
    """Frames every `every` steps of a midline sweep at 500 Hz."""
    env = EchoVectorEnv(SCAN_ID, 1, server=server, horizon=horizon, ultrasound=ultrasound,
                        controller={"kind": "hybrid_force_motion", "control_freq": 500.0},
                        task={"trajectory": "fixed", "early_termination": False})
    frames = []
    try:
        dt = env.echo_spec["dt_s"]
        obs, _ = env.reset(seed=seed)
        for step in range(horizon):
            obs, _, terminated, truncated, info = env.step(scripted_action(obs))
            if terminated[0] or truncated[0]:
                break
            if step % every == 0:
                frames.append({
                    "t": (step + 1) * dt,
                    "y_mm": 1000.0 * float(obs["probe_pose"][0][1]),
                    "force_n": float(info["contact_force"][0]),
                    "coupled": float(info["us_coupled"][0]),
                    "image": np.array(obs["ultrasound"][0]),
                })
    finally:
        env.close()
    return frames


def _show(ax, image: np.ndarray, ultrasound: dict, title: str) -> None:
    width = 1000.0 * ultrasound.get("aperture", 0.04)
    depth = 1000.0 * ultrasound.get("depth", 0.12)
    ax.imshow(image, cmap="gray", vmin=0, vmax=255, extent=[-width / 2, width / 2, depth, 0],
              interpolation="bilinear")
    ax.set_title(title, fontsize=8)
    ax.set_xlabel("array [mm]", fontsize=7)
    ax.tick_params(labelsize=6)


def write_figures(out: Path, press: list[dict], sites: list[dict], frames: list[dict],
                  ultrasound: dict) -> list[Path]:
    """press.png, sites.png, sweep.png and sweep.gif; the paths written."""
    plt = pyplot()
    from PIL import Image

    out.mkdir(parents=True, exist_ok=True)
    paths = []

    def panel(items: list[tuple[np.ndarray, str]], path: Path, suptitle: str) -> None:
        fig, axes = plt.subplots(1, len(items), figsize=(1.55 * len(items) + 0.4, 4.6),
                                 sharey=True)
        for ax, (image, title) in zip(np.atleast_1d(axes), items):
            _show(ax, image, ultrasound, title)
        np.atleast_1d(axes)[0].set_ylabel("depth below the face [mm]", fontsize=7)
        fig.suptitle(suptitle, fontsize=9)
        fig.tight_layout()
        fig.savefig(path, dpi=130)
        plt.close(fig)
        paths.append(path)

    panel([(p["image"], "in air (5 mm above)" if p["depth_mm"] is None else
            f"{p['depth_mm']:.0f} mm, {p['force_n']:.1f} N\ncoupled {p['coupled']:.0%}")
           for p in press], out / "press.png",
          "Over the kidney (site lower_left): in air, then pressed deeper")
    panel([(s["image"], f"{s['site']}\n{s['force_n']:.1f} N") for s in sites],
          out / "sites.png", "The seed's five sites, pressed 6 mm")
    strip = frames[:: max(1, len(frames) // 8)][:8]
    panel([(f["image"], f"t {f['t']:.1f} s, y {f['y_mm']:+.0f} mm\n{f['force_n']:.1f} N, "
            f"coupled {f['coupled']:.0%}") for f in strip], out / "sweep.png",
          "Midline sweep towards the head (UltrasoundScan-v0, hybrid controller, 5 N)")
    aspect = ultrasound.get("depth", 0.12) / ultrasound.get("aperture", 0.04)
    size = (160, int(round(160 * aspect)))
    gif = [Image.fromarray(f["image"]).resize(size, Image.BILINEAR) for f in frames]
    gif[0].save(out / "sweep.gif", save_all=True, append_images=gif[1:], duration=100, loop=0)
    paths.append(out / "sweep.gif")
    return paths


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="echogym ultrasound", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("ultrasound-output"))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--sweep-steps", type=int, default=3500,
                        help="sweep length in 500 Hz steps (default %(default)s = 7 s, 28 cm)")
    parser.add_argument("--config", default="{}",
                        help="JSON of the `ultrasound` settings (lines, rows, depth, "
                             "frequency_mhz, ...; default: the defaults)")
    parser.add_argument("--server", default=None,
                        help="server name (default $ECHOGYM_SERVER or 'default'; started if absent)")
    args = parser.parse_args(argv)
    if not plots_available("ultrasound"):
        return 2
    ultrasound = json.loads(args.config)
    client = echogym.connect(args.server, autostart=True)
    started = time.perf_counter()
    print("pressing over the kidney ...", flush=True)
    press = [press_image(client.name, "lower_left", d, args.seed, ultrasound)
             for d in (None, 0.002, 0.006, 0.010, 0.015)]
    print("pressing the five sites ...", flush=True)
    sites = []
    for site in SITES:
        sites.append({**press_image(client.name, site, 0.006, args.seed, ultrasound), "site": site})
    print("sweeping the midline ...", flush=True)
    frames = sweep(client.name, args.seed, args.sweep_steps, 50, ultrasound)
    paths = write_figures(args.out, press, sites, frames, ultrasound)
    for p in press:
        depth = "in air" if p["depth_mm"] is None else f"{p['depth_mm']:5.1f} mm"
        print(f"  kidney: depth {depth:>8}  force {p['force_n']:5.1f} N  "
              f"coupled {p['coupled']:.2f}  quality {p['quality']:.2f}")
    print(f"wrote {', '.join(str(p) for p in paths)} in {time.perf_counter() - started:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
