"""The torchrl adapter: `check_env_specs`, partial resets through `_reset` masks, lazy
attach (construction touches no server), and a `MultiSyncCollector` whose two spawned
worker processes each attach to the server and detach cleanly."""

import functools
import time

import pytest
import torch

pytest.importorskip("torchrl")

from tensordict import TensorDict  # noqa: E402
from torchrl.collectors import MultiSyncCollector  # noqa: E402
from torchrl.envs.utils import check_env_specs  # noqa: E402

from echogym.torchrl import EchoEnv  # noqa: E402


def test_check_env_specs(server):
    env = EchoEnv("echogym/Null-v0", num_envs=4, obs_size=16)
    check_env_specs(env)
    rollout = env.rollout(5)
    assert rollout["next", "obs"].shape == (4, 5, 16)
    torch.testing.assert_close(rollout["next", "obs"][..., 1:8], rollout["action"])
    env.close()


def test_construction_is_lazy_and_picklable(ipc):
    # No server is running: building (and pickling) the env must not need one.
    import pickle

    env = EchoEnv("echogym/Null-v0", num_envs=2, autostart=False)
    clone = pickle.loads(pickle.dumps(env))
    assert clone.batch_size == torch.Size([2])
    assert clone.observation_spec["obs"].shape == (2, 64)


def test_partial_reset_resets_only_masked_envs(server):
    env = EchoEnv("echogym/Null-v0", num_envs=3, max_episode_steps=None)
    td = env.reset()
    for _ in range(3):
        td = env.step(td.set("action", env.action_spec.rand()))["next"]
    mask = torch.tensor([[True], [False], [True]])
    # The server resets only masked envs and reports the others' current observation.
    out = env._reset(TensorDict({"_reset": mask}, batch_size=[3]))
    assert out["obs"][:, 0].tolist() == [0.0, 3.0, 0.0]
    # Through torchrl's public reset, as collectors call it.
    for _ in range(2):
        td = env.step(td.set("action", env.action_spec.rand()))["next"]
    out = env.reset(td.set("_reset", mask))
    assert out["obs"][:, 0].tolist() == [0.0, 5.0, 0.0]
    env.close()


def test_multisync_collector_with_two_worker_processes(server):
    make_env = functools.partial(EchoEnv, "echogym/Null-v0", num_envs=4, max_episode_steps=50)
    collector = MultiSyncCollector(
        [make_env, make_env],
        policy=None,
        frames_per_batch=400,
        total_frames=1200,
    )
    batches = 0
    for data in collector:
        batches += 1
        obs = data["next", "obs"]
        torch.testing.assert_close(obs[..., 1:8], data["action"])
        assert data.numel() == 400
    collector.shutdown()
    assert batches == 3
    deadline = time.monotonic() + 5
    while server.status()["leases"] and time.monotonic() < deadline:
        time.sleep(0.05)
    assert server.status()["leases"] == [], "workers left leases behind"
    assert server.status()["env_steps"] >= 1200


def test_zero_copy_mode_shares_memory_with_the_sample(server):
    env = EchoEnv("echogym/Null-v0", num_envs=2, copy_observations=False)
    td = env.reset()
    pointers = set()
    for _ in range(30):
        td = env.step(td.set("action", env.action_spec.rand()))["next"]
        pointers.add(td["obs"].data_ptr())
    assert len(pointers) <= 8, "observations are copied in zero-copy mode"
    copied = EchoEnv("echogym/Null-v0", num_envs=2)
    td = copied.reset()
    first = td["obs"]
    copied.step(td.set("action", copied.action_spec.rand()))
    assert first[:, 0].tolist() == [0.0, 0.0], "copied observations do not change"
    env.close()
    copied.close()
