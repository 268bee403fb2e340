"""stable-baselines3 on echogym: the `SB3VecEnv` adapter keeps SB3's conventions (ended
envs reset within the step, their last observation in `terminal_observation`, time-outs
flagged `TimeLimit.truncated` so SB3 bootstraps them), and the documented example
(`examples/sb3_ppo.py`) trains PPO on a server-side vector env, saves the model and
evaluates it, giving its lease back."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from echogym.train.sb3 import SB3VecEnv  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "sb3_ppo.py"


def test_adapter_follows_sb3_conventions(server):
    venv = SB3VecEnv("echogym/Null-v0", 3, obs_size=8, max_episode_steps=2)
    assert venv.observation_space.shape == (8,)
    venv.seed(5)
    obs = venv.reset()
    assert obs.shape == (3, 8) and obs.dtype == np.float32
    actions = np.full((3, venv.action_space.shape[0]), 0.5, np.float32)
    obs, reward, done, infos = venv.step(actions)
    assert not done.any() and len(infos) == 3
    np.testing.assert_allclose(reward, 0.5)  # Null-v0 rewards the first action element
    obs, reward, done, infos = venv.step(actions)
    assert done.all()
    for info in infos:
        assert info["TimeLimit.truncated"] is True
        # Null-v0 reports the step count in obs[0]: the final observation is step 2,
        # the returned one the fresh episode's first.
        assert info["terminal_observation"][0] == 2.0
    assert (obs[:, 0] == 0.0).all()
    venv.close()
    assert server.status()["leases"] == []


def test_sb3_example_trains_and_evaluates(server, tmp_path):
    out = tmp_path / "sb3"
    result = subprocess.run(
        [sys.executable, str(EXAMPLE), "--env-id", "echogym/PushCube-v0", "--num-envs", "4",
         "--total-timesteps", "512", "--n-steps", "64", "--batch-size", "64",
         "--eval-episodes", "4", "--out", str(out)],
        capture_output=True, text=True, timeout=600,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    report = json.loads((out / "eval.json").read_text())
    assert report["timesteps"] == 512
    assert report["episodes"] == 4 and 0.0 <= report["success_rate"] <= 1.0
    assert np.isfinite(report["return_mean"])
    assert (out / "model.zip").stat().st_size > 0 and (out / "vecnormalize.pkl").exists()
    deadline = time.monotonic() + 5
    while server.status()["leases"] and time.monotonic() < deadline:
        time.sleep(0.05)
    status = server.status()
    assert status["leases"] == [] and status["reclaimed_leases"] == 0
    assert status["env_steps"] >= 512
