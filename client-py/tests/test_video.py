"""Videos from real runs: `render_mode="rgb_array"` under gymnasium's own `RecordVideo`
wrappers (vector and single env) writes playable mp4s whose frames show the scene moving,
decoded back with imageio's ffmpeg reader."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import echogym  # noqa: F401 (registers the ids)

pytest.importorskip("moviepy")
imageio = pytest.importorskip("imageio.v2")


def decode(path) -> np.ndarray:
    reader = imageio.get_reader(str(path), format="FFMPEG")
    try:
        return np.stack([np.asarray(frame) for frame in reader])
    finally:
        reader.close()


def test_record_video_on_a_vector_env_writes_a_moving_tiled_mp4(server, tmp_path):
    envs = gym.make_vec("echogym/PushCube-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        render_mode="rgb_array", max_episode_steps=15)
    assert envs.metadata["render_fps"] == 20  # PushCube acts at 20 Hz
    assert "viewer_rgb" not in envs.single_observation_space.spaces
    envs = gym.wrappers.vector.RecordVideo(envs, str(tmp_path), episode_trigger=lambda e: e == 0,
                                           name_prefix="push")
    envs.reset(seed=3)
    action = np.zeros((2, 6), np.float32)
    action[:, 0] = 1.0  # sweep the probe along +x
    action[1, 2] = 1.0  # and env 1 upwards as well
    for _ in range(16):
        envs.step(action)
    envs.close()
    videos = sorted(tmp_path.glob("push-episode-0*.mp4"))
    assert len(videos) == 1, sorted(tmp_path.iterdir())
    frames = decode(videos[0])
    # Both envs side by side, each 256 × 256; the reset frame and the 14 steps before the
    # same-step autoreset (whose last frame RecordVideo leaves out).
    assert frames.shape[1:] == (256, 512, 3), frames.shape
    assert 12 <= len(frames) <= 16
    first, last = frames[0].astype(float), frames[-1].astype(float)
    for half in (slice(0, 256), slice(256, 512)):
        assert np.abs(first[:, half] - last[:, half]).mean() > 0.5
    # Not a blank picture: the shaded scene has many colours.
    assert len(np.unique(frames[0].reshape(-1, 3), axis=0)) > 200


def test_record_video_on_a_single_env_with_a_chosen_camera(server, tmp_path):
    env = gym.make("echogym/UltrasoundScan-v0", render_mode="rgb_array", max_episode_steps=20,
                   horizon=20, render_camera={"preset": "front", "width": 320, "height": 240})
    env = gym.wrappers.RecordVideo(env, str(tmp_path), episode_trigger=lambda e: True,
                                   name_prefix="scan", fps=25)
    env.reset(seed=0)
    action = np.zeros(env.action_space.shape, np.float32)
    action[2] = -1.0  # press down
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(action)
        done = terminated or truncated
    env.close()
    frames = decode(next(tmp_path.glob("scan-episode-0*.mp4")))
    assert frames.shape[1:] == (240, 320, 3)
    assert len(frames) >= 20
    assert np.abs(frames[0].astype(float) - frames[-1].astype(float)).mean() > 0.05


def test_render_mode_errors_are_clear(server):
    with pytest.raises(ValueError, match="render_mode must be one of"):
        echogym.EchoEnv("echogym/PushCube-v0", render_mode="human")
    with pytest.raises(ValueError, match="render_mode 'rgb_array' is not available"):
        echogym.EchoVectorEnv("echogym/Null-v0", 1, render_mode="rgb_array")
    with pytest.raises(ValueError, match="adds a camera named 'viewer'"):
        echogym.EchoVectorEnv("echogym/PushCube-v0", 1, render_mode="rgb_array",
                              cameras=[{"name": "viewer", "preset": "front"}])
    assert server.status()["leases"] == []
