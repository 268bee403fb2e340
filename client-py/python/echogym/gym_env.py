"""`EchoEnv`: one server-side env as a `gymnasium.Env`.

Observations are copied out of shared memory (gymnasium's env checker requires that
successive observations do not share memory); use :class:`echogym.EchoVectorEnv` or the
torchrl env for zero-copy batches.
"""

from __future__ import annotations

import json
from typing import Any

import gymnasium as gym
import numpy as np

from echogym import spaces as echo_spaces
from echogym.client import as_actions, connect
from echogym.episode import with_episode_length
from echogym.errors import InvalidConfigError
from echogym.render import render_config, render_fps, visible_fields


class EchoEnv(gym.Env):
    """A single echogym env hosted by a server (auto-started when none runs).

    Args:
        env_id: Versioned echogym id, e.g. ``"echogym/Null-v0"``.
        server: Server name (default ``$ECHOGYM_SERVER`` or ``"default"``).
        autostart: Start a private server if none is running (default true).
        render_mode: ``None``, ``"rgb_array"`` (:meth:`render` returns a 256 × 256
            smooth-shaded frame of the scene, from a viewing camera the server renders
            every step; for ``gymnasium.wrappers.RecordVideo``) or ``"rerun"`` (every step
            is logged to rerun's current recording; docs/viewer.md). What a render mode
            adds is hidden from the observations.
        render_camera: Keys overriding the viewing camera of ``"rgb_array"``
            (:data:`echogym.render.VIEW_CAMERA`), e.g. ``{"preset": "front", "width": 480}``.
        max_episode_steps: Episode length [steps], passed to the server as the env's
            length key (``horizon`` or ``max_episode_steps``) unless ``config`` sets
            that key; default the env's (see :mod:`echogym.episode`).
        **config: Env config; unknown keys raise :class:`echogym.InvalidConfigError`.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array", "rerun"]}

    def __init__(
        self,
        env_id: str,
        *,
        server: str | None = None,
        autostart: bool = True,
        render_mode: str | None = None,
        render_camera: dict[str, Any] | None = None,
        max_episode_steps: int | None = None,
        **config: Any,
    ) -> None:
        config, hidden = render_config(config, render_mode, render_camera)
        self.render_mode = render_mode
        self._client = connect(server, autostart=autostart)
        config = with_episode_length(env_id, config, max_episode_steps)
        try:
            self._lease = self._client.attach(env_id, 1, config, "disabled")
        except InvalidConfigError as exc:
            if render_mode is None:
                raise
            raise ValueError(f"render_mode {render_mode!r} is not available for {env_id}: {exc}") from exc
        #: The server's spec (every field, those of the render mode included).
        self.echo_spec: dict[str, Any] = json.loads(self._lease.spec_json)
        self._obs_spec, self._visible = visible_fields(self.echo_spec, hidden)
        self.metadata = {**self.metadata, **render_fps(self.echo_spec)}
        self._view_field = next((f["name"] for f in self.echo_spec["observation"]
                                 if f["name"] in hidden and f["name"].endswith("_rgb")), None)
        self._fields: tuple[np.ndarray, ...] = ()
        self._logger: Any = None
        if render_mode == "rerun":
            try:
                from echogym.rerun_log import RerunLogger

                self._logger = RerunLogger(self.echo_spec, num_envs=1)
            except BaseException:
                self._lease.close()  # no lease left behind by a failed start
                raise
        self.observation_space = echo_spaces.observation_space(self._obs_spec)
        self.action_space = echo_spaces.action_space(self.echo_spec)
        self._info_keys: list[str] = self.echo_spec["info_keys"]

    def _obs(self, fields: tuple[np.ndarray, ...]) -> Any:
        self._fields = fields
        return echo_spaces.obs_from_fields(self._obs_spec, tuple(fields[k][0].copy() for k in self._visible))

    def _info(self, info: np.ndarray) -> dict[str, float]:
        return {key: float(info[0, i]) for i, key in enumerate(self._info_keys)}

    def fields(self) -> dict[str, np.ndarray]:
        """Every field of the last step by name, shape ``(1, ...)``, those the render mode
        hides included (read-only views, valid until the next step)."""
        return {f["name"]: a for f, a in zip(self.echo_spec["observation"], self._fields)}

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Start a new episode; ``seed`` reseeds the server-side env."""
        super().reset(seed=seed)
        fields, _, _, _, info, _, _ = self._lease.reset(None, None if seed is None else [seed])
        obs = self._obs(fields)
        if self._logger is not None:
            self._logger.log_reset(self.fields(), {k: info[:, i] for i, k in enumerate(self._info_keys)})
        return obs, self._info(info)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Advance one step; ``action`` must be a float array of the action space's shape
        (the lease refuses anything else with :class:`echogym.InvalidActionError`, as a
        batch of one: shape ``(1, action_size)``)."""
        fields, reward, terminated, truncated, info, _, _ = self._lease.step(
            as_actions(action)[np.newaxis]
        )
        obs = self._obs(fields)
        if self._logger is not None:
            self._logger.log_step(self.fields(), reward, terminated, truncated,
                                  {k: info[:, i] for i, k in enumerate(self._info_keys)})
        return (
            obs,
            float(reward[0]),
            bool(terminated[0]),
            bool(truncated[0]),
            self._info(info),
        )

    def render(self) -> np.ndarray | None:
        """``rgb_array``: the viewing camera's frame of the last step (uint8 ``(h, w, 3)``
        copy); other modes: ``None`` (``rerun`` logs as it steps)."""
        if self.render_mode != "rgb_array" or not self._fields:
            return None
        return np.array(self.fields()[self._view_field][0])

    def close(self) -> None:
        """Give the lease back to the server."""
        lease = getattr(self, "_lease", None)
        if lease is not None:
            lease.close()
        super().close()
