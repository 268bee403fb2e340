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


def _same(a, b, label):
    assert set(a.keys(True, True)) == set(b.keys(True, True)), label
    for key in a.keys(True, True):
        x, y = a[key], b[key]
        assert x.dtype == y.dtype and x.shape == y.shape, (label, key)
        assert torch.equal(x, y), (label, key)


def test_worker_env_equals_the_transformed_env_it_replaces(server):
    # WorkerEnv (echogym.train.envs) computes in one pass what EchoEnv behind
    # CatTensors + RewardSum + StepCounter computed: same specs, same step data, same
    # next roots (through its direct step_and_maybe_reset and through torchrl's
    # generic path), episode ends and partial resets included.
    from torchrl.envs import CatTensors, Compose, RewardSum, StepCounter, TransformedEnv

    from echogym.train.envs import WorkerEnv, default_obs_keys, info_keys_for

    env_id, config = "echogym/PushCube-v0", {"horizon": 7}
    keys = default_obs_keys(env_id, config)
    info = info_keys_for(env_id, config)

    def reference():
        base = EchoEnv(env_id, 3, copy_observations=False, info_keys=info, **config)
        transforms = Compose(CatTensors(list(keys), "observation", del_keys=True),
                             RewardSum(), StepCounter())
        return TransformedEnv(base, transforms)

    def worker(fast=True):
        env = WorkerEnv(env_id, 3, keys, info_keys=info, **config)
        env.fast_step = fast
        return env

    envs = [reference(), worker(), worker(fast=False)]
    for name in ("full_observation_spec", "full_state_spec", "full_done_spec",
                 "full_reward_spec", "full_action_spec"):
        assert getattr(envs[1], name) == getattr(envs[0], name), name
    check_env_specs(envs[1])

    actions = torch.rand(20, 3, 6, generator=torch.Generator().manual_seed(0)) * 0.6 - 0.3
    runs = []
    for env in envs:
        env.set_seed(5)
        td = env.reset()
        # Root entries that step_mdp carries over (a policy output, collector data).
        td.set("collector", TensorDict({"traj_ids": torch.arange(3)}, [3]))
        steps, roots = [], []
        for t in range(20):  # three episode ends (horizon 7)
            td.set("action", actions[t])
            td.set("loc", 2 * actions[t])
            data, td = env.step_and_maybe_reset(td)
            steps.append(data.clone())
            roots.append(td.clone())
        assert int(steps[-1]["next", "step_count"][0]) == 6
        # A partial reset through torchrl's public reset, as collectors call it.
        td.set("_reset", torch.tensor([[True], [False], [True]]))
        roots.append(env.reset(td).clone())
        runs.append((torch.stack(steps), roots))
        env.close()
    for i in (1, 2):
        _same(runs[0][0], runs[i][0], f"steps {i}")
        for t, (a, b) in enumerate(zip(runs[0][1], runs[i][1])):
            _same(a, b, f"root {i} {t}")
    after_reset = runs[1][1][-1]
    assert after_reset["step_count"][:, 0].tolist() == [0, 6, 0]
    assert after_reset["episode_reward"][1] != 0 and after_reset["episode_reward"][0] == 0
