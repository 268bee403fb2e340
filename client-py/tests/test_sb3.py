"""stable-baselines3 on echogym: the `SB3VecEnv` adapter keeps SB3's conventions (ended
envs reset within the step, their last observation in `terminal_observation`, time-outs
flagged `TimeLimit.truncated` so SB3 bootstraps them), passes camera images in a `Dict`
observation that `MultiInputPolicy` trains on, and the documented example
(`examples/sb3_ppo.py`) trains PPO on a server-side vector env, saves the model and
evaluates it, giving its lease back."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from echogym.sb3 import SB3VecEnv  # noqa: E402

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


def test_images_arrive_in_a_dict_and_multi_input_ppo_learns(server):
    from stable_baselines3 import PPO

    venv = SB3VecEnv("echogym/PushCube-v0", 2, horizon=4,
                     cameras=[{"name": "front", "width": 64, "height": 64}])
    space = venv.observation_space
    assert isinstance(space, gym.spaces.Dict)
    assert space["front_rgb"].shape == (64, 64, 3) and space["front_rgb"].dtype == np.uint8
    assert space["front_depth"].shape == (64, 64, 1)  # 2-D fields get a channel axis
    assert space["joint_pos"].shape == (7,)
    assert set(venv.obs_keys) == set(space.spaces)  # nothing dropped
    obs = venv.reset()
    assert obs["front_rgb"].shape == (2, 64, 64, 3) and obs["front_rgb"].any()
    assert space.contains({k: v[0] for k, v in obs.items()})
    actions = np.zeros((2, venv.action_space.shape[0]), np.float32)
    for _ in range(4):
        obs, _, done, infos = venv.step(actions)
    assert done.all()
    final = infos[0]["terminal_observation"]
    assert isinstance(final, dict) and final["front_rgb"].shape == (64, 64, 3)
    model = PPO("MultiInputPolicy", venv, n_steps=8, batch_size=8, n_epochs=1, seed=0,
                device="cpu")
    model.learn(total_timesteps=16)
    assert model.num_timesteps == 16
    action, _ = model.predict(venv.reset(), deterministic=True)
    assert action.shape == (2, venv.action_space.shape[0])
    venv.close()
    assert server.status()["leases"] == []


def test_vectors_only_stay_one_flat_box(server):
    venv = SB3VecEnv("echogym/PushCube-v0", 2, obs_keys=["joint_pos", "task_errors"])
    assert venv.observation_space.shape == (7 + 12,)
    assert venv.reset().shape == (2, 19)
    venv.close()


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
