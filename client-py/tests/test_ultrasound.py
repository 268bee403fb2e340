"""The `ultrasound` observation through the real server and shared memory: its space,
no signal in air, an image on contact under the hybrid controller, determinism under a
seed, and the `echogym ultrasound` figures command."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

from echogym.apps.sweep_policy import scripted_action
from echogym.gym_vector import EchoVectorEnv

SCAN = "echogym/UltrasoundScan-v0"
HYBRID = {"kind": "hybrid_force_motion", "control_freq": 500.0}


def _rollout(server, seed: int, steps: int):
    env = EchoVectorEnv(SCAN, 2, server=server.name, controller=HYBRID,
                        task={"trajectory": "fixed"}, ultrasound={"lines": 64, "rows": 96})
    try:
        obs, info = env.reset(seed=seed)
        first = (np.array(obs["ultrasound"]), np.array(info["us_coupled"]))
        for _ in range(steps):
            obs, _, _, _, info = env.step(scripted_action(obs))
        return env.observation_space, first, np.array(obs["ultrasound"]), info
    finally:
        env.close()


def test_image_appears_on_contact_and_follows_the_seed(server):
    space, (image0, coupled0), image, info = _rollout(server, seed=4, steps=400)
    assert space["ultrasound"].shape == (2, 96, 64)
    assert space["ultrasound"].dtype == np.uint8
    # The probe starts 5 mm above the skin: nothing at all.
    assert image0.shape == (2, 96, 64)
    assert not image0.any()
    assert (coupled0 == 0).all()
    # After 0.8 s the controller holds 5 N on the skin: coupled, and tissue is imaged.
    assert (info["us_coupled"] > 0.9).all(), info["us_coupled"]
    assert (info["us_quality"] > 0.4).all(), info["us_quality"]
    assert image.mean() > 20
    _, _, again, _ = _rollout(server, seed=4, steps=400)
    assert np.array_equal(image, again)


def test_ultrasound_command_writes_figures(server, tmp_path):
    out = tmp_path / "us"
    done = subprocess.run(
        [sys.executable, "-m", "echogym", "ultrasound", "--server", server.name,
         "--out", str(out), "--sweep-steps", "600", "--config", '{"lines": 64, "rows": 64}'],
        capture_output=True, text=True, timeout=300,
    )
    assert done.returncode == 0, done.stderr
    for name in ("press.png", "sites.png", "sweep.png", "sweep.gif"):
        assert (out / name).stat().st_size > 1000, name
    assert "kidney: depth   in air" in done.stdout
