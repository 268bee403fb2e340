"""Merge the Rust and MuJoCo physics benchmark JSON into the markdown table of
`benches/run physics`, write benches/results/physics.md (+ .json), print a RESULT line."""

from __future__ import annotations

import json
import os
import sys
import time

from bench_server import machine_description

TARGET_PRESS_SLIDE = 10_000


def main(rust_path: str, mujoco_path: str) -> None:
    ours = json.load(open(rust_path))
    peer = json.load(open(mujoco_path)) if os.path.exists(mujoco_path) else {}

    def mj(key: str) -> str:
        s = peer.get(key, {})
        return f"{s['steps_per_s']:,.0f}" if "steps_per_s" in s else "n/a"

    def mj_counts(key: str) -> str:
        s = peer.get(key, {})
        return f"{s.get('vertices', '-')} vert / {s.get('dofs', '-')} DoF" if s else ""

    r = {k: v["steps_per_s"] for k, v in ours.items()}
    scaling = (r["torso_press"] / r["torso_press_2x"]) / (
        ours["torso_press_2x"]["particles"] / ours["torso_press"]["particles"]
    )
    press = r["arm_press_slide"]
    best_mj_soft = max(
        (peer.get(k, {}).get("steps_per_s", 0) for k in ("arm_press_slide",)), default=0
    )
    lines = [
        f"### Physics benchmark ({time.strftime('%Y-%m-%d')}, {machine_description()})",
        "",
        "Physics steps/s on one core, 2 ms steps, median of the runs. echogym: rapier3d 0.36 "
        f"+ echogym's particle torso; MuJoCo {peer.get('mujoco_version', 'n/a')} "
        f"(flexcomp torso, support: {peer.get('config', {}).get('torso_support', 'n/a')}) measured in the same run.",
        "",
        "| scene | echogym | counts | MuJoCo | counts |",
        "|---|---:|---|---:|---|",
        f"| (a) torso alone, probe pressing 8 mm and sliding | {r['torso_press']:,.0f} | "
        f"{ours['torso_press']['particles']} particles | {mj('torso_alone')} | {mj_counts('torso_alone')} |",
        f"| (a) torso alone, 2× particles | {r['torso_press_2x']:,.0f} | "
        f"{ours['torso_press_2x']['particles']} particles | | |",
        f"| (a) torso as calibration replays it (10 % of the mass) | {r['torso_replay']:,.0f} | "
        f"{ours['torso_replay']['particles']} particles | | |",
        f"| (a) design B: particles as rapier rigid bodies | {r['torso_rigid_bodies']:,.0f} | "
        f"{ours['torso_rigid_bodies']['bodies']} bodies | | |",
        f"| (b) arm alone (Panda, gravity compensation each step) | {r['arm_alone']:,.0f} | 7 DoF | "
        f"{mj('arm_alone')} | {mj_counts('arm_alone')} |",
        f"| (c) arm pressing 1 cm and sliding on the torso (OSC each step) | {press:,.0f} | "
        f"7 DoF + {ours['arm_press_slide']['particles']} particles, "
        f"{ours['arm_press_slide']['press_force_n']:.1f} N | {mj('arm_press_slide')} | "
        f"{mj_counts('arm_press_slide')} |",
        "",
        f"- Target (c) ≥ {TARGET_PRESS_SLIDE:,} steps/s: "
        + ("met" if press >= TARGET_PRESS_SLIDE else f"**missed** ({press / TARGET_PRESS_SLIDE:.0%} of it)"),
        f"- (c) vs MuJoCo's (c): {press / best_mj_soft:.1f}×" if best_mj_soft else "- MuJoCo (c): n/a",
        f"- 2× particles cost {r['torso_press'] / r['torso_press_2x']:.2f}× the time per step "
        f"(linear would be {ours['torso_press_2x']['particles'] / ours['torso_press']['particles']:.2f}×; "
        f"ratio {scaling:.2f})",
        "",
    ]
    table = "\n".join(lines)
    print(table)
    here = os.path.dirname(os.path.abspath(__file__))
    os.makedirs(os.path.join(here, "results"), exist_ok=True)
    with open(os.path.join(here, "results", "physics.md"), "w") as f:
        f.write(table)
    with open(os.path.join(here, "results", "physics.json"), "w") as f:
        json.dump({"machine": machine_description(), "echogym": ours, "mujoco": peer}, f, indent=1)
    keys = {
        "torso_press": r["torso_press"],
        "torso_press_2x": r["torso_press_2x"],
        "torso_replay": r["torso_replay"],
        "torso_rigid_bodies": r["torso_rigid_bodies"],
        "arm_alone": r["arm_alone"],
        "arm_press_slide": press,
        "mujoco_torso_alone": peer.get("torso_alone", {}).get("steps_per_s", float("nan")),
        "mujoco_arm_alone": peer.get("arm_alone", {}).get("steps_per_s", float("nan")),
        "mujoco_arm_press_slide": peer.get("arm_press_slide", {}).get("steps_per_s", float("nan")),
        "scaling_ratio": scaling,
    }
    print("RESULT " + " ".join(f"{k}={v:.4g}" for k, v in keys.items()))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
