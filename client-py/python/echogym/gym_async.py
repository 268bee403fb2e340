"""`EchoAsyncVectorEnv`: envpool's asynchronous API over echogym envs, and gymnasium's
``step_async`` / ``step_wait``.

``num_envs`` envs are leased as groups of ``group_size`` (one lease each, see
ARCHITECTURE.md "Async batches"). ``send(actions, env_id)`` steps envs and returns at
once; ``recv()`` returns the first ``batch_size`` envs whose observations are ready, with
their ids in ``info["env_id"]``: while the policy computes on those, the server steps
the others. With ``batch_size == num_envs`` it is a synchronous vector env.

Unlike :class:`echogym.EchoVectorEnv`, what ``recv`` returns are fresh arrays (the rows of
several groups' samples gathered), so they can be kept.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from echogym import spaces as echo_spaces
from echogym.client import as_actions, connect
from echogym.episode import with_episode_length
from echogym.errors import EchogymError

_MODES = {"same_step": AutoresetMode.SAME_STEP, "disabled": AutoresetMode.DISABLED}


class EchoAsyncVectorEnv(VectorEnv):
    """``num_envs`` echogym envs stepped asynchronously, envpool-style.

    Args:
        env_id: Versioned echogym id.
        num_envs: All envs (N).
        batch_size: Envs ``recv`` returns (M, default ``num_envs``: synchronous).
        group_size: Envs per lease, the unit of asynchrony (default ``batch_size``); must
            divide ``batch_size`` and ``num_envs``. Smaller groups let a slow env hold up
            fewer others, at one lease (three shared-memory services) per group.
        server: Server name (default ``$ECHOGYM_SERVER`` or ``"default"``).
        autostart: Start a private server if none is running (default true).
        autoreset_mode: ``"same_step"`` (default) or ``"disabled"``, as for
            :class:`echogym.EchoVectorEnv`.
        max_episode_steps: Episode length [steps] (see :mod:`echogym.episode`).
        **config: Env config; unknown keys raise :class:`echogym.InvalidConfigError`.
    """

    def __init__(
        self,
        env_id: str,
        num_envs: int,
        batch_size: int | None = None,
        *,
        group_size: int | None = None,
        server: str | None = None,
        autostart: bool = True,
        autoreset_mode: str | AutoresetMode = "same_step",
        max_episode_steps: int | None = None,
        **config: Any,
    ) -> None:
        mode = autoreset_mode.value if isinstance(autoreset_mode, AutoresetMode) else autoreset_mode
        if mode not in _MODES:
            raise ValueError(f"autoreset_mode must be 'same_step' or 'disabled', got {mode!r}")
        batch_size = num_envs if batch_size is None else batch_size
        group_size = batch_size if group_size is None else group_size
        if not 0 < batch_size <= num_envs:
            raise ValueError(f"batch_size must be in 1..num_envs ({num_envs}), got {batch_size}")
        if group_size <= 0 or batch_size % group_size or num_envs % group_size:
            raise ValueError(
                f"group_size ({group_size}) must divide batch_size ({batch_size}) and "
                f"num_envs ({num_envs})"
            )
        self.num_envs = num_envs
        self.batch_size = batch_size
        self.group_size = group_size
        self.autoreset_mode = _MODES[mode]
        config = with_episode_length(env_id, config, max_episode_steps)
        self._client = connect(server, autostart=autostart)
        self._batch = self._client.attach_async(env_id, num_envs, group_size, config, mode)
        #: The server's spec.
        self.echo_spec: dict[str, Any] = json.loads(self._batch.spec_json)
        self.metadata = {"autoreset_mode": self.autoreset_mode}
        self.single_observation_space = echo_spaces.observation_space(self.echo_spec)
        self.single_action_space = echo_spaces.action_space(self.echo_spec)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._info_keys: list[str] = self.echo_spec["info_keys"]
        self._last_ids = np.arange(num_envs, dtype=np.int64)

    # -- envpool's API ---------------------------------------------------------------

    def async_reset(self, seed: int | list[int | None] | None = None) -> None:
        """Reset every env and return at once; ``recv`` takes the observations.
        ``seed``: an int (env ``i`` gets ``seed + i``) or one seed per env."""
        ids = np.arange(self.num_envs, dtype=np.int64)
        self._batch.send_reset(ids, _seeds(seed, self.num_envs))

    def send(self, actions: Any, env_id: Any = None) -> None:
        """Step the envs ``env_id`` (default: those the last ``recv`` returned) with
        ``actions`` (row ``i`` for env ``env_id[i]``) and return at once."""
        ids = self._last_ids if env_id is None else np.asarray(env_id, dtype=np.int64)
        self._batch.send_step(as_actions(actions), ids)

    def recv(self) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """The first ``batch_size`` envs whose observations are ready: ``(obs, reward,
        terminated, truncated, info)`` with ``info["env_id"]`` their ids."""
        return self._gather(self._batch.recv(self.batch_size), ordered=False)

    # -- gymnasium's API ---------------------------------------------------------------

    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[Any, dict[str, Any]]:
        """Reset every env and wait for all of them (rows in env id order)."""
        if options:
            raise ValueError(f"options are not supported by the async vector env: {options}")
        self._drain()
        self.async_reset(seed)
        obs, _, _, _, info = self._gather(self._batch.recv(self.num_envs), ordered=True)
        return obs, info

    def step_async(self, actions: Any) -> None:
        """Step every env (``actions`` in env id order) and return at once."""
        self.send(actions, np.arange(self.num_envs, dtype=np.int64))

    def step_wait(self) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Wait for every env sent (rows in env id order)."""
        return self._gather(self._batch.recv(self.num_envs), ordered=True)

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env and wait for all of them."""
        self.step_async(actions)
        return self.step_wait()

    def close_extras(self, **kwargs: Any) -> None:
        """Give every lease back to the server."""
        self._batch.close()

    # -- assembling a batch from groups -------------------------------------------------

    def _drain(self) -> None:
        """Receive whatever is still in flight (a reset starts from a clean slate)."""
        while self._batch.pending_envs:
            try:
                self._batch.recv(self.num_envs)
            except EchogymError:
                pass  # a refused step of an env about to be reset

    def _gather(
        self, groups: list[int], ordered: bool
    ) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        if ordered:
            groups = sorted(groups)
        views = [self._batch.views(g) for g in groups]
        ids = np.concatenate(
            [np.arange(g * self.group_size, (g + 1) * self.group_size) for g in groups]
        ).astype(np.int64)
        self._last_ids = ids

        def cat(index: int) -> np.ndarray:
            return np.concatenate([v[index] for v in views])

        fields = tuple(
            np.concatenate([v[0][k] for v in views]) for k in range(len(views[0][0]))
        )
        reward, terminated, truncated, info = cat(1), cat(2), cat(3), cat(4)
        infos: dict[str, Any] = {key: info[:, i] for i, key in enumerate(self._info_keys)}
        infos["env_id"] = ids
        if views[0][5] is not None:
            done = terminated | truncated
            if done.any():
                final_fields = tuple(
                    np.concatenate([v[5][k] for v in views]) for k in range(len(fields))
                )
                final_info = np.concatenate([v[6] for v in views])
                final_obs = np.empty(len(ids), dtype=object)
                final_infos = np.empty(len(ids), dtype=object)
                for i in np.flatnonzero(done):
                    final_obs[i] = echo_spaces.obs_from_fields(
                        self.echo_spec, tuple(f[i] for f in final_fields)
                    )
                    final_infos[i] = {
                        key: float(final_info[i, j]) for j, key in enumerate(self._info_keys)
                    }
                infos["final_obs"], infos["_final_obs"] = final_obs, done.copy()
                infos["final_info"], infos["_final_info"] = final_infos, done.copy()
        obs = echo_spaces.obs_from_fields(self.echo_spec, fields)
        return obs, reward, terminated, truncated, infos


def _seeds(seed: int | list[int | None] | None, n: int) -> list[int | None] | None:
    if seed is None:
        return None
    seeds = [seed + i for i in range(n)] if isinstance(seed, int) else list(seed)
    if len(seeds) != n:
        raise ValueError(f"expected {n} seeds, got {len(seeds)}")
    return seeds
