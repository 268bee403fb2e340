"""`EchoVectorEnv`: a batch of server-side envs as one `gymnasium.vector.VectorEnv`.

One exchange with the server steps the whole batch (in parallel on the server's
workers). Observations, rewards and flags are **read-only numpy views onto shared
memory, valid until the next** ``step``/``reset``; copy what you keep longer.

An env that fails inside the server (its code panicked) fails alone: ``infos["env_error"]``
is 1 for it (every env declares the key), its observation row is zeros, a failed step is
truncated and the env needs a reset (with ``"same_step"`` autoreset the server resets it
within the step); the other envs' results are as usual.
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
from echogym.errors import InvalidConfigError
from echogym.render import render_config, render_fps, visible_fields

_MODES = {"same_step": AutoresetMode.SAME_STEP, "disabled": AutoresetMode.DISABLED}


class EchoVectorEnv(VectorEnv):
    """``num_envs`` echogym envs stepped with one shared-memory exchange.

    Args:
        env_id: Versioned echogym id.
        num_envs: Envs in the batch.
        server: Server name (default ``$ECHOGYM_SERVER`` or ``"default"``).
        autostart: Start a private server if none is running (default true).
        autoreset_mode: ``"same_step"`` (default: ended envs restart within the step;
            the last observation is in ``infos["final_obs"]``) or ``"disabled"``
            (reset ended envs with ``reset(options={"reset_mask": mask})``).
        render_mode: ``None``, ``"rgb_array"`` (:meth:`render` returns one 256 × 256
            smooth-shaded frame per env, from a viewing camera the server renders every
            step; for ``gymnasium.wrappers.vector.RecordVideo``) or ``"rerun"`` (every
            step is logged to rerun's current recording; docs/viewer.md). What a render
            mode adds is hidden from the observations.
        render_camera: Keys overriding the viewing camera of ``"rgb_array"``
            (:data:`echogym.render.VIEW_CAMERA`), e.g. ``{"preset": "front", "width": 480}``.
        max_episode_steps: Episode length [steps], passed to the server as the env's
            length key (``horizon`` or ``max_episode_steps``) unless ``config`` sets
            that key; default the env's (see :mod:`echogym.episode`).
        **config: Env config; unknown keys raise :class:`echogym.InvalidConfigError`.
    """

    def __init__(
        self,
        env_id: str,
        num_envs: int = 1,
        *,
        server: str | None = None,
        autostart: bool = True,
        autoreset_mode: str | AutoresetMode = "same_step",
        render_mode: str | None = None,
        render_camera: dict[str, Any] | None = None,
        max_episode_steps: int | None = None,
        **config: Any,
    ) -> None:
        mode = autoreset_mode.value if isinstance(autoreset_mode, AutoresetMode) else autoreset_mode
        if mode not in _MODES:
            raise ValueError(f"autoreset_mode must be 'same_step' or 'disabled', got {mode!r}")
        config, hidden = render_config(config, render_mode, render_camera)
        self.autoreset_mode = _MODES[mode]
        self.render_mode = render_mode
        self.num_envs = num_envs
        config = with_episode_length(env_id, config, max_episode_steps)
        self._client = connect(server, autostart=autostart)
        try:
            self._lease = self._client.attach(env_id, num_envs, config, mode)
        except InvalidConfigError as exc:
            if render_mode is None:
                raise
            raise ValueError(f"render_mode {render_mode!r} is not available for {env_id}: {exc}") from exc
        #: The server's spec (every field, those of the render mode included).
        self.echo_spec: dict[str, Any] = json.loads(self._lease.spec_json)
        self._obs_spec, self._visible = visible_fields(self.echo_spec, hidden)
        self.metadata = {"autoreset_mode": self.autoreset_mode, "render_modes": ["rgb_array", "rerun"],
                         **render_fps(self.echo_spec)}
        self._fields: tuple[np.ndarray, ...] = ()
        self._logger: Any = None
        if render_mode == "rerun":
            try:
                from echogym.rerun_log import RerunLogger

                self._logger = RerunLogger(self.echo_spec, num_envs=num_envs)
            except BaseException:
                self._lease.close()  # no lease left behind by a failed start
                raise
        self._view_field = next((f["name"] for f in self.echo_spec["observation"]
                                 if f["name"] in hidden and f["name"].endswith("_rgb")), None)
        self.single_observation_space = echo_spaces.observation_space(self._obs_spec)
        self.single_action_space = echo_spaces.action_space(self.echo_spec)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._info_keys: list[str] = self.echo_spec["info_keys"]
        self._all = np.ones(num_envs, dtype=bool)

    def _infos(self, info: np.ndarray) -> dict[str, Any]:
        infos: dict[str, Any] = {}
        for i, key in enumerate(self._info_keys):
            infos[key] = info[:, i]
            infos["_" + key] = self._all
        return infos

    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[Any, dict[str, Any]]:
        """Reset all envs (or those in ``options["reset_mask"]``).

        ``seed`` is an int (env ``i`` gets ``seed + i``) or one seed per env.
        """
        if isinstance(seed, int):
            seeds: list[int | None] | None = [seed + i for i in range(self.num_envs)]
        else:
            seeds = seed
        if seeds is not None and len(seeds) != self.num_envs:
            raise ValueError(f"expected {self.num_envs} seeds, got {len(seeds)}")
        mask = None
        if options is not None and "reset_mask" in options:
            mask = np.asarray(options["reset_mask"], dtype=bool)
            if mask.shape != (self.num_envs,):
                raise ValueError(f"reset_mask must have shape ({self.num_envs},)")
        fields, _, _, _, info, _, _ = self._lease.reset(mask, seeds)
        self._fields = fields
        if self._logger is not None:
            self._logger.log_reset(self.fields(), self._infos(info), mask)
        return self._obs(fields), self._infos(info)

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env with ``actions`` (shape ``(num_envs, action_size)``, floating
        point; the lease refuses anything else with :class:`echogym.InvalidActionError`)."""
        fields, reward, terminated, truncated, info, final_fields, final_info = self._lease.step(
            as_actions(actions)
        )
        infos = self._infos(info)
        self._fields = fields
        if self._logger is not None:
            self._logger.log_step(self.fields(), reward, terminated, truncated, infos)
        if final_fields is not None:
            done = terminated | truncated
            if done.any():
                final_obs = np.empty(self.num_envs, dtype=object)
                final_infos = np.empty(self.num_envs, dtype=object)
                for i in np.flatnonzero(done):
                    final_obs[i] = echo_spaces.obs_from_fields(
                        self._obs_spec, tuple(final_fields[k][i].copy() for k in self._visible)
                    )
                    final_infos[i] = {
                        key: float(final_info[i, j]) for j, key in enumerate(self._info_keys)
                    }
                infos["final_obs"] = final_obs
                infos["_final_obs"] = done.copy()
                infos["final_info"] = final_infos
                infos["_final_info"] = done.copy()
        return self._obs(fields), reward, terminated, truncated, infos

    def _obs(self, fields: tuple[np.ndarray, ...]) -> Any:
        return echo_spaces.obs_from_fields(self._obs_spec, tuple(fields[k] for k in self._visible))

    def fields(self) -> dict[str, np.ndarray]:
        """Every field of the last step by name, shape ``(num_envs, ...)``, those the
        render mode hides included (read-only views, valid until the next step)."""
        return {f["name"]: a for f, a in zip(self.echo_spec["observation"], self._fields)}

    def render(self) -> tuple[np.ndarray, ...] | None:
        """``rgb_array``: one frame per env (uint8 ``(h, w, 3)`` copies) of the last
        step; other modes: ``None`` (``rerun`` logs as it steps)."""
        if self.render_mode != "rgb_array" or not self._fields:
            return None
        frames = self.fields()[self._view_field]
        return tuple(np.array(frame) for frame in frames)

    def close_extras(self, **kwargs: Any) -> None:
        """Give the lease back to the server."""
        self._lease.close()
