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


class EchoEnv(gym.Env):
    """A single echogym env hosted by a server (auto-started when none runs).

    Args:
        env_id: Versioned echogym id, e.g. ``"echogym/Null-v0"``.
        server: Server name (default ``$ECHOGYM_SERVER`` or ``"default"``).
        autostart: Start a private server if none is running (default true).
        render_mode: ``None`` or ``"rgb_array"`` (then :meth:`render` returns the first
            configured camera's RGB image; configure one with ``cameras=[...]``).
        max_episode_steps: Episode length [steps], passed to the server as the env's
            length key (``horizon`` or ``max_episode_steps``) unless ``config`` sets
            that key; default the env's (see :mod:`echogym.episode`).
        **config: Env config; unknown keys raise :class:`echogym.InvalidConfigError`.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"]}

    def __init__(
        self,
        env_id: str,
        *,
        server: str | None = None,
        autostart: bool = True,
        render_mode: str | None = None,
        max_episode_steps: int | None = None,
        **config: Any,
    ) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode {render_mode!r} is not supported by {env_id}")
        self.render_mode = render_mode
        self._client = connect(server, autostart=autostart)
        config = with_episode_length(env_id, config, max_episode_steps)
        self._lease = self._client.attach(env_id, 1, config, "disabled")
        self.echo_spec: dict[str, Any] = json.loads(self._lease.spec_json)
        rgb = [f["name"] for f in self.echo_spec["observation"] if f["name"].endswith("_rgb")]
        if render_mode == "rgb_array" and not rgb:
            self._lease.close()
            raise ValueError(f"render_mode 'rgb_array' needs a camera with rgb: pass cameras=[{{'name': 'front'}}]")
        self._render_field = rgb[0] if rgb else None
        self._last_obs: Any = None
        self.observation_space = echo_spaces.observation_space(self.echo_spec)
        self.action_space = echo_spaces.action_space(self.echo_spec)
        self._info_keys: list[str] = self.echo_spec["info_keys"]

    def _obs(self, fields: tuple[np.ndarray, ...]) -> Any:
        return echo_spaces.obs_from_fields(self.echo_spec, tuple(f[0].copy() for f in fields))

    def _info(self, info: np.ndarray) -> dict[str, float]:
        return {key: float(info[0, i]) for i, key in enumerate(self._info_keys)}

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Start a new episode; ``seed`` reseeds the server-side env."""
        super().reset(seed=seed)
        fields, _, _, _, info, _, _ = self._lease.reset(None, None if seed is None else [seed])
        self._last_obs = self._obs(fields)
        return self._last_obs, self._info(info)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Advance one step; ``action`` must be a float array of the action space's shape
        (the lease refuses anything else with :class:`echogym.InvalidActionError`, as a
        batch of one: shape ``(1, action_size)``)."""
        fields, reward, terminated, truncated, info, _, _ = self._lease.step(
            as_actions(action)[np.newaxis]
        )
        self._last_obs = self._obs(fields)
        return (
            self._last_obs,
            float(reward[0]),
            bool(terminated[0]),
            bool(truncated[0]),
            self._info(info),
        )

    def render(self) -> np.ndarray | None:
        """The first camera's RGB image of the last observation (``rgb_array`` mode)."""
        if self.render_mode != "rgb_array" or self._last_obs is None:
            return None
        return self._last_obs[self._render_field].copy()

    def close(self) -> None:
        """Give the lease back to the server."""
        lease = getattr(self, "_lease", None)
        if lease is not None:
            lease.close()
        super().close()
