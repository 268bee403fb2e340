"""The physics envs (UltrasoundScan, PushCube, CalibrationPress) through a real server:
gymnasium `check_env` and torchrl `check_env_specs` for every id, seeded determinism,
zero-copy camera images in the vector env, a 2-worker `MultiSyncCollector` on the scan,
nested configs with errors naming the key, and recordings written by the press."""

import functools
import json
import time

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium.utils.env_checker import check_env

import echogym
from conftest import Server

PHYSICS_IDS = ["echogym/UltrasoundScan-v0", "echogym/PushCube-v0", "echogym/CalibrationPress-v0"]


@pytest.mark.parametrize("env_id", PHYSICS_IDS)
def test_check_env_passes(server, env_id):
    env = gym.make(env_id, horizon=50)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("env_id", PHYSICS_IDS)
def test_check_env_specs_passes(server, env_id):
    from torchrl.envs.utils import check_env_specs

    from echogym.torchrl import EchoEnv

    env = EchoEnv(env_id, num_envs=2, horizon=50)
    check_env_specs(env)
    env.close()


@pytest.mark.parametrize("env_id", PHYSICS_IDS)
def test_seeded_rollouts_are_reproducible(server, env_id):
    def rollout(seed):
        env = gym.make(env_id, horizon=50)
        obs, _ = env.reset(seed=seed)
        rng = np.random.default_rng(0)
        trace = [obs["probe_pose"]]
        for _ in range(10):
            obs, reward, *_ = env.step(rng.uniform(-0.3, 0.3, env.action_space.shape).astype(np.float32))
            trace.append(np.append(obs["probe_pose"], reward))
        env.close()
        return np.concatenate(trace)

    np.testing.assert_array_equal(rollout(5), rollout(5))
    assert not np.array_equal(rollout(5), rollout(6))


def test_camera_images_are_zero_copy_views(server):
    envs = gym.make_vec(
        "echogym/UltrasoundScan-v0",
        num_envs=2,
        vectorization_mode="vector_entry_point",
        cameras=[{"name": "front", "width": 32, "height": 32}],
    )
    obs, _ = envs.reset(seed=0)
    rgb, depth = obs["front_rgb"], obs["front_depth"]
    assert rgb.shape == (2, 32, 32, 3) and rgb.dtype == np.uint8
    assert depth.shape == (2, 32, 32) and depth.dtype == np.float32
    for array in (rgb, depth, obs["ft"]):
        assert not array.flags.owndata and not array.flags.writeable
        base = array
        while isinstance(base, np.ndarray):
            base = base.base
        assert type(base).__name__ == "SampleMemory", "image copied out of the sample"
    assert len(np.unique(rgb[0])) > 5, "a flat image"
    addresses = set()
    for _ in range(20):
        obs, *_ = envs.step(np.zeros(envs.action_space.shape, np.float32))
        addresses.add(obs["front_rgb"].__array_interface__["data"][0])
    assert len(addresses) <= 8, "camera images are copied"
    envs.close()


def test_multisync_collector_collects_the_scan_with_two_workers(server):
    from torchrl.collectors import MultiSyncCollector

    from echogym.torchrl import EchoEnv

    make_env = functools.partial(EchoEnv, "echogym/UltrasoundScan-v0", num_envs=2, horizon=100)
    collector = MultiSyncCollector([make_env, make_env], policy=None, frames_per_batch=200,
                                   total_frames=400)
    frames = 0
    for data in collector:
        frames += data.numel()
        assert torch.isfinite(data["next", "reward"]).all()
        assert data["next", "ft"].shape[-1] == 6
    collector.shutdown()
    assert frames == 400
    deadline = time.monotonic() + 5
    while server.status()["leases"] and time.monotonic() < deadline:
        time.sleep(0.05)
    assert server.status()["leases"] == [], "workers left leases behind"


def test_nested_config_and_errors_name_the_key(server):
    env = gym.make("echogym/UltrasoundScan-v0", robot="ur5e", task={"target_force": 6.0},
                   controller={"kind": "hybrid_force_motion"})
    obs, _ = env.reset(seed=0)
    assert obs["joint_pos"].shape == (6,), "the UR5e has six joints"
    config = json.loads(json.dumps(env.unwrapped.echo_spec["config"]))
    assert config["task"]["target_force"] == 6.0
    env.close()
    with pytest.raises(echogym.InvalidConfigError, match="target_forse"):
        gym.make("echogym/UltrasoundScan-v0", task={"target_forse": 6.0})
    with pytest.raises(echogym.InvalidConfigError, match="randomization.torso_damping"):
        gym.make("echogym/UltrasoundScan-v0", randomization={"torso_damping": [41, 17]})
    assert server.status()["leases"] == []


def test_calibration_press_records_a_dataset(ipc, tmp_path):
    # Recordings are confined to the server's recordings root: this server's is tmp_path.
    server = Server("pytest", ipc, "--recordings-root", str(tmp_path))
    with pytest.raises(echogym.InvalidConfigError, match="record.dir.*outside"):
        gym.make("echogym/CalibrationPress-v0", record={"dir": "/etc/echogym"})
    with pytest.raises(echogym.InvalidConfigError, match=r"record.dir.*\.\."):
        gym.make("echogym/CalibrationPress-v0", record={"dir": "../escape"})
    env = gym.make("echogym/CalibrationPress-v0", task={"site": "upper_left", "hold_time": 0.2},
                   record={"dir": str(tmp_path)})
    env.reset(seed=0)
    terminated = False
    steps = 0
    while not terminated:
        _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape, np.float32))
        steps += 1
        assert not truncated
    assert info["is_success"] == 1.0
    env.close()
    deadline = time.monotonic() + 5
    while not list(tmp_path.glob("*/dataset.json")) and time.monotonic() < deadline:
        time.sleep(0.05)
    (dataset,) = list(tmp_path.glob("*/dataset.json"))
    meta = json.loads(dataset.read_text())
    assert meta["format"] == "echogym-recordings/1"
    assert meta["recordings"][0]["site"] == "upper_left"
    csv = dataset.parent / meta["recordings"][0]["file"]
    header, *rows = csv.read_text().splitlines()
    assert header.split(",")[:7] == ["t", "px", "py", "pz", "fx", "fy", "fz"]
    assert len(rows) >= steps
    assert server.stop() == 0


def test_rgb_array_render_mode_returns_the_viewing_camera_image(server):
    env = gym.make("echogym/PushCube-v0", render_mode="rgb_array",
                   cameras=[{"name": "bird", "width": 48, "height": 32}])
    obs, _ = env.reset(seed=0)
    frame = env.render()
    # The 256 × 256 viewing camera, not the observation's 48 × 32 one (kept in obs).
    assert frame.shape == (256, 256, 3) and frame.dtype == np.uint8
    assert obs["bird_rgb"].shape == (32, 48, 3) and "viewer_rgb" not in obs
    env.close()
    env = gym.make("echogym/PushCube-v0", render_mode="rgb_array",
                   render_camera={"preset": "bird", "width": 48, "height": 32})
    env.reset(seed=0)
    assert env.render().shape == (32, 48, 3)
    env.close()
    assert server.status()["leases"] == []
