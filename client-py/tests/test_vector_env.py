"""The gymnasium vector adapter: one shared-memory exchange per batch, read-only views
onto the server's sample (zero copy), same-step autoreset with final observations, and
disabled autoreset with reset masks; `make_vec` hands the registered episode length to
the server under the env's own key."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import echogym


def make(num_envs, **kwargs):
    return gym.make_vec(
        "echogym/Null-v0", num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs
    )


def test_spaces_and_metadata(server):
    envs = make(4)
    assert envs.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    assert envs.autoreset_mode == AutoresetMode.SAME_STEP
    assert envs.single_observation_space.shape == (64,)
    assert envs.observation_space.shape == (4, 64)
    assert envs.action_space.shape == (4, 7)
    envs.close()


def test_observations_are_read_only_views_onto_shared_memory(server):
    envs = make(8)
    obs, info = envs.reset(seed=0)
    for array in (obs, info["episode_step"]):
        assert not array.flags.writeable
        assert not array.flags.owndata
    base = obs
    while isinstance(base, np.ndarray):
        base = base.base
    assert type(base).__name__ == "SampleMemory", "the array's memory is the lease's sample"
    # The server publishes into a few fixed sample slots: after a handful of steps the
    # returned arrays reuse the same memory instead of fresh copies.
    addresses = set()
    for _ in range(50):
        obs, *_ = envs.step(np.zeros((8, 7), np.float32))
        addresses.add(obs.__array_interface__["data"][0])
    assert len(addresses) <= 8, f"{len(addresses)} distinct buffers: observations are copied"
    with pytest.raises(ValueError):
        obs[0, 0] = 1.0
    envs.close()


def test_every_observation_matches_its_action(server):
    envs = make(16, max_episode_steps=None)
    envs.reset(seed=1)
    rng = np.random.default_rng(0)
    for step in range(1, 201):
        actions = rng.uniform(-1, 1, (16, 7)).astype(np.float32)
        obs, reward, terminated, truncated, info = envs.step(actions)
        np.testing.assert_array_equal(obs[:, 1:8], actions)
        np.testing.assert_array_equal(obs[:, 0], step)
        np.testing.assert_array_equal(reward, actions[:, 0])
    envs.close()


def test_same_step_autoreset_reports_final_observation(server):
    envs = make(3, max_episode_steps=2)
    envs.reset(seed=0)
    envs.step(np.zeros((3, 7), np.float32))
    obs, _, terminated, truncated, info = envs.step(np.full((3, 7), 0.5, np.float32))
    assert truncated.all() and not terminated.any()
    np.testing.assert_array_equal(obs[:, 0], 0)
    assert info["_final_obs"].all()
    assert info["final_obs"][1][0] == 2 and info["final_obs"][1][1] == 0.5
    assert info["final_info"][0]["episode_step"] == 2
    envs.close()


def test_disabled_autoreset_uses_reset_masks(server):
    envs = make(3, max_episode_steps=1, autoreset_mode="disabled")
    envs.reset(seed=0)
    _, _, _, truncated, _ = envs.step(np.zeros((3, 7), np.float32))
    assert truncated.all()
    with pytest.raises(echogym.NeedsResetError, match="env 0"):
        envs.step(np.zeros((3, 7), np.float32))
    obs, _ = envs.reset(options={"reset_mask": np.array([True, True, True])})
    np.testing.assert_array_equal(obs[:, 0], 0)
    envs.step(np.zeros((3, 7), np.float32))
    envs.close()


def test_wrong_batch_shape_is_refused(server):
    envs = make(4)
    envs.reset()
    with pytest.raises(echogym.InvalidActionError, match=r"\(4, 7\)"):
        envs.step(np.zeros((3, 7), np.float32))
    envs.step(np.zeros((4, 7), np.float32))
    envs.close()


def test_make_vec_sets_the_episode_length_under_the_envs_key(server):
    def pushcube(**kwargs):
        return gym.make_vec("echogym/PushCube-v0", num_envs=2,
                            vectorization_mode="vector_entry_point", **kwargs)

    envs = pushcube()  # make_vec passes the registered max_episode_steps (200)
    assert envs.echo_spec["max_episode_steps"] == 200
    envs.close()
    envs = pushcube(max_episode_steps=3)  # as `horizon`, PushCube's key
    assert envs.echo_spec["max_episode_steps"] == 3
    envs.reset(seed=0)
    truncated = [envs.step(np.zeros((2, 6), np.float32))[3].copy() for _ in range(3)]
    assert not truncated[1].any() and truncated[2].all()
    envs.close()
    envs = pushcube(horizon=5)  # the env's own key wins over the registered default
    assert envs.echo_spec["max_episode_steps"] == 5
    envs.close()
