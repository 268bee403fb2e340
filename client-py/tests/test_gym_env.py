"""The single-env gymnasium adapter against a real server: `check_env`, data integrity,
typed errors for bad actions and configs (the env keeps working), seeding, closing, and
the episode length on the registered specs and through `max_episode_steps`."""

import json

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import echogym
from echogym import _native


def test_check_env_passes(server):
    env = gym.make("echogym/Null-v0")
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_observation_echoes_action_and_counts_steps(server):
    env = gym.make("echogym/Null-v0", obs_size=16, action_size=3)
    obs, info = env.reset(seed=1)
    assert obs.shape == (16,) and obs.dtype == np.float32
    assert info == {"episode_step": 0.0, "env_error": 0.0}
    for step in range(1, 6):
        action = np.array([0.1 * step, -0.2, 0.3], dtype=np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        assert obs[0] == step
        np.testing.assert_array_equal(obs[1:4], action)
        assert reward == pytest.approx(0.1 * step)
        assert not terminated and not truncated
        assert info["episode_step"] == step
    env.close()


def test_bad_actions_raise_typed_errors_and_lose_nothing(server):
    env = gym.make("echogym/Null-v0").unwrapped
    env.reset(seed=0)
    env.step(np.zeros(7, np.float32))
    # The lease checks every action, as a batch of one env.
    with pytest.raises(echogym.InvalidActionError, match=r"shape \(1, 7\), got \[1, 6\]"):
        env.step(np.zeros(6, np.float32))
    with pytest.raises(echogym.InvalidActionError, match="float32 .* got int64"):
        env.step(np.zeros(7, np.int64))
    nan = np.zeros(7, np.float32)
    nan[2] = np.nan
    with pytest.raises(echogym.InvalidActionError, match="env 0 element 2"):
        env.step(nan)
    with pytest.raises(echogym.InvalidActionError):
        env.step(np.full(7, np.inf))
    obs, *_ = env.step(np.full(7, 0.5, np.float64))
    assert obs[0] == 2, "refused steps did not advance the env"
    env.close()


def test_bad_configs_and_ids_are_rejected_naming_the_key(server):
    with pytest.raises(echogym.InvalidConfigError, match="obs_sise"):
        gym.make("echogym/Null-v0", obs_sise=3)
    with pytest.raises(echogym.InvalidConfigError, match="`obs_size`"):
        gym.make("echogym/Null-v0", obs_size=0)
    with pytest.raises(echogym.UnknownEnvError, match="echogym/Null-v0"):
        echogym.EchoEnv("echogym/Missing-v0")
    assert server.status()["leases"] == []


def test_seeded_episodes_are_reproducible(server):
    def rollout(seed):
        env = gym.make("echogym/Null-v0")
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for _ in range(5):
            out.append(env.step(np.full(7, 0.25, np.float32))[0])
        env.close()
        return np.stack(out)

    np.testing.assert_array_equal(rollout(3), rollout(3))
    assert not np.array_equal(rollout(3), rollout(4))


def test_closed_env_raises_and_frees_its_lease(server):
    env = gym.make("echogym/Null-v0")
    env.reset()
    assert len(server.status()["leases"]) == 1
    env.close()
    assert server.status()["leases"] == []
    with pytest.raises(echogym.EnvClosedError):
        env.unwrapped.step(np.zeros(7, np.float32))


def test_version_mismatch_is_a_typed_error(server):
    client = echogym.connect()
    with pytest.raises(echogym.VersionMismatchError, match="protocol 999"):
        client.native.request('{"op": "status"}', protocol_version=999)


def test_connect_without_server_names_the_problem(ipc):
    with pytest.raises(echogym.ServerNotRunningError, match="echogym serve --name nobody"):
        echogym.connect("nobody")


def test_registered_specs_carry_the_episode_length():
    for env_id, _ in echogym.registered_envs():
        default = json.loads(_native.resolve_spec(env_id, "{}"))["max_episode_steps"]
        assert gym.spec(env_id).max_episode_steps == default > 0, env_id
    assert gym.spec("echogym/PushCube-v0").max_episode_steps == 200


def test_max_episode_steps_sets_the_servers_episode_length(server):
    env = echogym.EchoEnv("echogym/Null-v0", max_episode_steps=3)
    assert env.echo_spec["max_episode_steps"] == 3
    env.reset(seed=0)
    flags = [env.step(np.zeros(7, np.float32))[3] for _ in range(3)]
    assert flags == [False, False, True]
    env.close()
    # The physics envs' key is `horizon`; given explicitly, it wins.
    env = echogym.EchoEnv("echogym/PushCube-v0", max_episode_steps=7)
    assert env.echo_spec["max_episode_steps"] == 7
    env.close()
    env = echogym.EchoEnv("echogym/PushCube-v0", max_episode_steps=7, horizon=9)
    assert env.echo_spec["max_episode_steps"] == 9
    env.close()


def test_gym_make_limits_episodes_at_the_registered_length(server):
    env = gym.make("echogym/Null-v0")
    assert env.spec.max_episode_steps == 1000
    env.close()
    env = gym.make("echogym/Null-v0", max_episode_steps=2)  # gymnasium's TimeLimit
    env.reset(seed=0)
    assert [env.step(np.zeros(7, np.float32))[3] for _ in range(2)] == [False, True]
    env.close()
