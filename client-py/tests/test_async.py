"""Asynchronous batches (envpool's `send`/`recv`, gymnasium's `step_async`/`step_wait`)
against a real server: every env's observations equal a synchronous run's with the same
seeds and actions, ids come back right, nothing is lost, misuse is refused by name."""

import numpy as np
import pytest

import echogym
from echogym.gym_async import EchoAsyncVectorEnv

PHYSICS = "echogym/PushCube-v0"


def action_for(env: int, k: int, size: int) -> np.ndarray:
    """The action env `env` takes at its `k`-th step (any order of arrival gives the same)."""
    return np.random.default_rng([env, k]).uniform(-0.5, 0.5, size).astype(np.float32)


def sync_run(num_envs: int, steps: int, seed: int) -> list[list[np.ndarray]]:
    envs = echogym.EchoVectorEnv(PHYSICS, num_envs, max_episode_steps=None)
    size = envs.single_action_space.shape[0]
    obs, _ = envs.reset(seed=seed)
    trace = [[np.array(obs["probe_pose"][e])] for e in range(num_envs)]
    for k in range(steps):
        actions = np.stack([action_for(e, k, size) for e in range(num_envs)])
        obs, *_ = envs.step(actions)
        for e in range(num_envs):
            trace[e].append(np.array(obs["probe_pose"][e]))
    envs.close()
    return trace


def test_send_recv_matches_a_synchronous_run(server):
    n, batch, steps, seed = 8, 4, 12, 3
    expected = sync_run(n, steps, seed)
    envs = EchoAsyncVectorEnv(PHYSICS, n, batch, group_size=2, max_episode_steps=None)
    size = envs.single_action_space.shape[0]
    envs.async_reset(seed=seed)
    trace: list[list[np.ndarray]] = [[] for _ in range(n)]
    done_envs: set[int] = set()
    seen_orders = set()
    pending = n
    while len(done_envs) < n:
        obs, reward, terminated, truncated, info = envs.recv()
        ids = info["env_id"]
        # `batch` envs, or all that are pending when fewer are (groups arrive in the
        # order they finish, so some groups may run out of steps before others).
        want = min(batch, pending)
        assert len(ids) == want and len(set(ids.tolist())) == want
        pending -= len(ids)
        seen_orders.add(tuple(ids.tolist()))
        for row, e in enumerate(ids):
            trace[e].append(np.array(obs["probe_pose"][row]))
        send_ids = [e for e in ids if len(trace[e]) <= steps]
        done_envs.update(e for e in ids if len(trace[e]) > steps)
        if send_ids:
            # Envs of a group finish together (same number of steps), so what is sent is
            # whole groups.
            k = [len(trace[e]) - 1 for e in send_ids]
            envs.send(np.stack([action_for(e, kk, size) for e, kk in zip(send_ids, k)]),
                      np.array(send_ids))
            pending += len(send_ids)
    for e in range(n):
        assert len(trace[e]) == steps + 1, f"env {e} got {len(trace[e])} observations"
        np.testing.assert_array_equal(np.stack(trace[e]), np.stack(expected[e]),
                                      err_msg=f"env {e}")
    envs.close()
    assert server.status()["leases"] == []


def test_gymnasium_step_async_equals_step(server):
    n, steps = 6, 10
    expected = sync_run(n, steps, seed=5)
    envs = EchoAsyncVectorEnv(PHYSICS, n, group_size=2, max_episode_steps=None)
    size = envs.single_action_space.shape[0]
    obs, info = envs.reset(seed=5)
    np.testing.assert_array_equal(info["env_id"], np.arange(n))
    for k in range(steps):
        envs.step_async(np.stack([action_for(e, k, size) for e in range(n)]))
        obs, reward, terminated, truncated, info = envs.step_wait()
        assert reward.shape == (n,) and terminated.shape == (n,)
        np.testing.assert_array_equal(info["env_id"], np.arange(n))
    np.testing.assert_array_equal(obs["probe_pose"],
                                  np.stack([expected[e][-1] for e in range(n)]))
    # What recv returns is a copy: it survives later steps.
    kept = obs["probe_pose"].copy()
    envs.step(np.zeros((n, size), np.float32))
    np.testing.assert_array_equal(obs["probe_pose"], kept)
    envs.close()


def test_every_action_reaches_its_env(server):
    # Null-v0 echoes the action in obs[1:8] and counts steps in obs[0]: over many rounds
    # of first-ready batches, each env's observation carries its own last action and
    # step count.
    n, batch = 8, 2
    envs = EchoAsyncVectorEnv("echogym/Null-v0", n, batch, group_size=1, max_episode_steps=None)
    envs.async_reset(seed=0)
    counts = np.zeros(n, int)
    last = np.zeros((n, 7), np.float32)
    rng = np.random.default_rng(0)
    for _ in range(300):
        obs, _, _, _, info = envs.recv()
        ids = info["env_id"]
        np.testing.assert_array_equal(obs[:, 0], counts[ids])
        np.testing.assert_array_equal(obs[:, 1:8], last[ids])
        actions = rng.uniform(-1, 1, (len(ids), 7)).astype(np.float32)
        last[ids] = actions
        counts[ids] += 1
        envs.send(actions, ids)
    envs.close()
    assert counts.sum() == 300 * batch


def test_misuse_is_refused_naming_the_env(server):
    envs = EchoAsyncVectorEnv("echogym/Null-v0", 4, 2, group_size=2)
    envs.async_reset(seed=0)
    _, _, _, _, info = envs.recv()
    ids = info["env_id"]
    other = [e for e in range(4) if e not in ids]
    zeros = np.zeros((1, 7), np.float32)
    with pytest.raises(ValueError, match=f"env {ids[0]} is sent without env {ids[1]}"):
        envs.send(zeros, ids[:1])
    with pytest.raises(ValueError, match=f"env id {other[0]} was sent|env {other[0]} was sent"):
        envs.send(np.zeros((2, 7), np.float32), other)
    with pytest.raises(ValueError, match="out of range"):
        envs.send(np.zeros((2, 7), np.float32), [4, 5])
    with pytest.raises(echogym.InvalidActionError):
        envs.send(np.zeros((3, 7), np.float32), ids)
    with pytest.raises(ValueError, match="group_size"):
        EchoAsyncVectorEnv("echogym/Null-v0", 4, 2, group_size=3)
    envs.close()


def test_torchrl_async_collector_pairs_each_env_with_its_own_transitions(server):
    torch = pytest.importorskip("torch")
    from tensordict.nn import TensorDictModule

    from echogym.torchrl_async import AsyncCollector

    class RandomPolicy(torch.nn.Module):
        def forward(self, observation):
            return torch.rand(observation.shape[0], 7) * 2 - 1

    policy = TensorDictModule(RandomPolicy(), in_keys=["observation"], out_keys=["action"])
    collector = AsyncCollector("echogym/Null-v0", 8, 4, policy, frames_per_batch=64,
                               total_frames=256, group_size=2, seed=0, max_episode_steps=20)
    batches = 0
    last_step = {}
    for data in collector:
        batches += 1
        assert data.numel() == 64
        obs, action, nxt = data["observation"], data["action"], data["next", "observation"]
        # Null-v0 echoes the action and counts the episode's steps in obs[0].
        torch.testing.assert_close(nxt[:, 1:8], action)
        bad = (nxt[:, 0] != obs[:, 0] + 1).nonzero().flatten()
        assert len(bad) == 0, f"transitions whose step count does not follow: {bad.tolist()}"
        done = data["next", "done"].squeeze(-1)
        assert (done == (nxt[:, 0] == 20)).all(), "episodes end at the horizon"
        # An env's transitions come in order: each starts where its previous one ended
        # (or from its reset).
        for row in range(64):
            env = int(data["env_id"][row])
            if env in last_step:
                prev_next, prev_done = last_step[env]
                expected = 0.0 if prev_done else prev_next
                assert float(obs[row, 0]) == expected, f"env {env} skipped a transition"
            last_step[env] = (float(nxt[row, 0]), bool(done[row]))
    collector.shutdown()
    assert batches == 4
    assert sorted(last_step) == list(range(8))
