"""stable-baselines3 on echogym: :class:`SB3VecEnv` adapts :class:`echogym.EchoVectorEnv`
(one lease, a batch of server-side envs stepped with one shared-memory exchange) to SB3's
``VecEnv`` API.

Observations: when every field passed is a 1-D float vector (the envs' default fields),
one flat ``Box`` of the fields concatenated, for ``MlpPolicy`` and ``VecNormalize`` as in
the seed; with images (cameras' ``*_rgb``/``*_depth``, ``ultrasound``) a ``Dict`` by field
name for ``MultiInputPolicy``, every field kept. 2-D fields (depth, ultrasound) get a
trailing channel axis, ``(H, W)`` → ``(H, W, 1)``, so SB3 reads the uint8 ones as images.

SB3 expects its own conventions, which the adapter provides: ``reset()`` returns only the
observations (infos in ``reset_infos``), ``step_wait()`` returns ``dones = terminated |
truncated`` and one info dict per env, an ended env is reset within the step (the vector
env's same-step autoreset) with its last observation in ``info["terminal_observation"]``
and ``info["TimeLimit.truncated"]`` set for time-outs, so SB3 bootstraps them. Arrays are
copied out of shared memory (SB3 keeps them in its rollout buffer).

Needs ``pip install 'echogym[sb3]'``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvStepReturn

from echogym.gym_vector import EchoVectorEnv

__all__ = ["SB3VecEnv"]

Observation = np.ndarray | dict[str, np.ndarray]


class SB3VecEnv(VecEnv):
    """``num_envs`` echogym envs as an SB3 ``VecEnv``.

    Args:
        env_id: Versioned echogym id.
        num_envs: Envs in the batch (one server lease).
        obs_keys: Observation fields to pass, in order (default: every field the env
            declares). All 1-D float vectors: one flat ``Box``; otherwise a ``Dict``.
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
        fields = [f["name"] for f in self.venv.echo_spec["observation"]]
        if not isinstance(space, gym.spaces.Dict):  # a single field: the vector env's Box
            space = gym.spaces.Dict({fields[0]: space})
        self._fields = fields
        self.obs_keys = list(fields if obs_keys is None else obs_keys)
        unknown = [k for k in self.obs_keys if k not in space.spaces]
        if unknown:
            self.venv.close()
            raise ValueError(f"{env_id} has no observation fields {unknown}; it declares {fields}")
        chosen = {k: space[k] for k in self.obs_keys}
        self.flat = all(
            isinstance(sub, gym.spaces.Box) and len(sub.shape) == 1 and sub.dtype == np.float32
            for sub in chosen.values()
        )
        self._channel = {k for k, sub in chosen.items() if len(sub.shape) == 2}
        observation_space: gym.spaces.Space
        if self.flat:
            low = np.concatenate([chosen[k].low for k in self.obs_keys]).astype(np.float32)
            high = np.concatenate([chosen[k].high for k in self.obs_keys]).astype(np.float32)
            observation_space = gym.spaces.Box(low, high, dtype=np.float32)
        else:
            observation_space = gym.spaces.Dict({k: self._with_channel(k, sub)
                                                 for k, sub in chosen.items()})
        self.render_mode = None
        super().__init__(num_envs, observation_space, self.venv.single_action_space)
        self.info_keys: list[str] = self.venv.echo_spec["info_keys"]
        self._actions: np.ndarray | None = None

    def _with_channel(self, key: str, space: gym.spaces.Box) -> gym.spaces.Box:
        if key not in self._channel:
            return space
        return gym.spaces.Box(space.low[..., np.newaxis], space.high[..., np.newaxis],
                              dtype=space.dtype)

    def _convert(self, obs: Observation) -> Observation:
        """The vector env's observation (a batch, or one env's) in this env's space, copied."""
        fields = obs if isinstance(obs, dict) else {self._fields[0]: obs}
        if self.flat:
            return np.concatenate(
                [np.asarray(fields[k], dtype=np.float32) for k in self.obs_keys], axis=-1
            )
        return {k: np.array(fields[k])[..., np.newaxis] if k in self._channel
                else np.array(fields[k]) for k in self.obs_keys}

    def reset(self) -> Observation:
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        obs, infos = self.venv.reset(seed=seeds)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = self._info_list(infos, np.zeros(self.num_envs, bool),
                                           np.zeros(self.num_envs, bool))
        return self._convert(obs)

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
                out[i]["terminal_observation"] = self._convert(infos["final_obs"][i])
                out[i].update(infos["final_info"][i])
                out[i]["is_success"] = bool(out[i].get("is_success", 0.0) > 0.5)
        return self._convert(obs), np.array(reward, dtype=np.float32), done, out

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
