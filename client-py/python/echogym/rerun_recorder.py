"""Gymnasium wrappers that log every step of an echogym env to rerun.

``RerunRecorder(env)`` for a ``gymnasium.Env`` (``gym.make``), ``RerunVectorRecorder(envs)``
for a vector env (``gym.make_vec``). The env must deliver the scene state: create it with
``scene_state=True`` (the fields then also appear in its observations) — or use
``render_mode="rerun"``, which logs the same way with the fields hidden. The logged
entities are described in :mod:`echogym.rerun_log`; saving: ``rr.save(path)`` before
stepping, or ``recording=`` a stream of your own.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import VectorEnv, VectorWrapper

from echogym.render import SCENE_FIELDS
from echogym.rerun_log import RerunLogger

__all__ = ["RerunRecorder", "RerunVectorRecorder"]


def _echo_env(env: Any) -> Any:
    inner = env.unwrapped
    spec = getattr(inner, "echo_spec", None)
    if spec is None or not hasattr(inner, "fields"):
        raise TypeError(f"{type(inner).__name__} is not an echogym env (no echo_spec)")
    names = [f["name"] for f in spec["observation"]]
    if not all(name in names for name in SCENE_FIELDS):
        raise ValueError(f"{spec['env_id']} was made without the scene state: create it with "
                         "scene_state=True (or render_mode='rerun')")
    return inner


class RerunRecorder(gym.Wrapper):
    """Log each reset and step of a single echogym env to rerun.

    Args:
        env: An echogym env made with ``scene_state=True``.
        recording: A ``rerun.RecordingStream`` (default rerun's global recording).
        every: Log every ``every``-th step.
    """

    def __init__(self, env: gym.Env, *, recording: Any = None, every: int = 1) -> None:
        super().__init__(env)
        self._inner = _echo_env(env)
        self.logger = RerunLogger(self._inner.echo_spec, 1, recording=recording, every=every)

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        self.logger.log_reset(self._inner.fields(), {k: np.array([v]) for k, v in info.items()})
        return obs, info

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.logger.log_step(self._inner.fields(), np.array([reward]), np.array([terminated]),
                             np.array([truncated]), {k: np.array([v]) for k, v in info.items()})
        return obs, reward, terminated, truncated, info


class RerunVectorRecorder(VectorWrapper):
    """Log each reset and step of an echogym vector env to rerun.

    Args:
        env: An echogym vector env made with ``scene_state=True``.
        recording: A ``rerun.RecordingStream`` (default rerun's global recording).
        envs: Which envs to log (default all).
        every: Log every ``every``-th step.
    """

    def __init__(self, env: VectorEnv, *, recording: Any = None, envs: Sequence[int] | None = None,
                 every: int = 1) -> None:
        super().__init__(env)
        self._inner = _echo_env(env)
        self.logger = RerunLogger(self._inner.echo_spec, env.num_envs, recording=recording,
                                  envs=envs, every=every)

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        obs, infos = self.env.reset(**kwargs)
        self.logger.log_reset(self._inner.fields(), infos)
        return obs, infos

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict[str, Any]]:
        obs, reward, terminated, truncated, infos = self.env.step(actions)
        self.logger.log_step(self._inner.fields(), reward, terminated, truncated, infos)
        return obs, reward, terminated, truncated, infos
