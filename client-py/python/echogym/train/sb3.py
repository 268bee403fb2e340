"""stable-baselines3 (the seed's stack) on echogym: :class:`SB3VecEnv` adapts
:class:`echogym.EchoVectorEnv` (one lease, a batch of server-side envs stepped with one
shared-memory exchange) to SB3's ``VecEnv`` API, with the observation fields concatenated
into one ``Box`` so ``MlpPolicy`` and ``VecNormalize`` apply as in the seed.

SB3 expects its own conventions, which the adapter provides: ``reset()`` returns only the
observations (infos in ``reset_infos``), ``step_wait()`` returns ``dones = terminated |
truncated`` and one info dict per env, an ended env is reset within the step (the vector
env's same-step autoreset) with its last observation in ``info["terminal_observation"]``
and ``info["TimeLimit.truncated"]`` set for time-outs, so SB3 bootstraps them. Arrays are
copied out of shared memory (SB3 keeps them in its rollout buffer).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvStepReturn

from echogym.gym_vector import EchoVectorEnv


class SB3VecEnv(VecEnv):
    """``num_envs`` echogym envs as an SB3 ``VecEnv`` with a flat ``Box`` observation.

    Args:
        env_id: Versioned echogym id.
        num_envs: Envs in the batch (one server lease).
        obs_keys: Observation fields to concatenate, in order (default: every 1-D
            float field, i.e. no camera images and no particle state).
        server: Server name (default ``$ECHOGYM_SERVER`` or ``"default"``).
        **config: Env config; unknown keys raise :class:`echogym.InvalidConfigError`.
    """

    def __init__(
        self,
        env_id: str,
        num_envs: int,
        *,
        obs_keys: Sequence[str] | None = None,
        server: str | None = None,
        **config: Any,
    ) -> None:
        self.venv = EchoVectorEnv(env_id, num_envs, server=server, autoreset_mode="same_step",
                                  **config)
        space = self.venv.single_observation_space
        if not isinstance(space, gym.spaces.Dict):  # a single field: the vector env's Box
            field = self.venv.echo_spec["observation"][0]["name"]
            space = gym.spaces.Dict({field: space})
        self._single = len(self.venv.echo_spec["observation"]) == 1
        if obs_keys is None:
            obs_keys = [
                key for key, sub in space.spaces.items()
                if isinstance(sub, gym.spaces.Box) and len(sub.shape) == 1
                and sub.dtype == np.float32
            ]
        self.obs_keys = list(obs_keys)
        low = np.concatenate([space[k].low for k in self.obs_keys]).astype(np.float32)
        high = np.concatenate([space[k].high for k in self.obs_keys]).astype(np.float32)
        observation_space = gym.spaces.Box(low, high, dtype=np.float32)
        self.render_mode = None
        super().__init__(num_envs, observation_space, self.venv.single_action_space)
        self.info_keys: list[str] = self.venv.echo_spec["info_keys"]
        self._actions: np.ndarray | None = None

    def _flat(self, obs: dict[str, np.ndarray] | np.ndarray) -> np.ndarray:
        if self._single:
            return np.array(obs, dtype=np.float32)
        return np.concatenate([np.asarray(obs[k], dtype=np.float32) for k in self.obs_keys], axis=-1)

    def reset(self) -> np.ndarray:
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        obs, infos = self.venv.reset(seed=seeds)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = self._info_list(infos, np.zeros(self.num_envs, bool),
                                           np.zeros(self.num_envs, bool))
        return self._flat(obs)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions, dtype=np.float32).reshape(self.num_envs, -1)

    def step_wait(self) -> VecEnvStepReturn:
        assert self._actions is not None, "step_async first"
        obs, reward, terminated, truncated, infos = self.venv.step(self._actions)
        terminated = np.array(terminated, dtype=bool)
        truncated = np.array(truncated, dtype=bool)
        done = terminated | truncated
        out = self._info_list(infos, terminated, truncated)
        if done.any():
            for i in np.flatnonzero(done):
                out[i]["terminal_observation"] = self._flat(infos["final_obs"][i])
                out[i].update(infos["final_info"][i])
                out[i]["is_success"] = bool(out[i].get("is_success", 0.0) > 0.5)
        return self._flat(obs), np.array(reward, dtype=np.float32), done, out

    def _info_list(
        self, infos: dict[str, Any], terminated: np.ndarray, truncated: np.ndarray
    ) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        for i in range(self.num_envs):
            info = {key: float(infos[key][i]) for key in self.info_keys}
            info["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            out.append(info)
        return out

    def close(self) -> None:
        self.venv.close()

    # SB3's per-env attribute access: the envs live in the server, so only the adapter's
    # own attributes are reachable.
    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self, attr_name)] * len(self._get_indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        setattr(self, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:
        raise NotImplementedError(f"{method_name}: echogym envs run in the server")

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper],
                       indices: VecEnvIndices = None) -> list[bool]:
        return [False] * len(self._get_indices(indices))
