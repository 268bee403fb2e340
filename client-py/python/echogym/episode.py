"""Episode length: the server ends every episode itself (``truncated``) after the env's
length, set by the env's own config key (``horizon`` for the physics envs,
``max_episode_steps`` for ``echogym/Null-v0``), default in its spec
(``max_episode_steps``).

gymnasium registers each id with that default as ``spec.max_episode_steps``; the adapters
also accept gymnasium's ``max_episode_steps`` keyword and pass it to the server under the
env's key, so ``gym.make_vec`` (which hands the registered value to the vector env) and a
caller's ``max_episode_steps=N`` set the same length. The env's own key, when given, wins.
"""

from __future__ import annotations

import json
from typing import Any

from echogym._native import resolve_spec

#: The config keys that set an env's episode length [steps].
LENGTH_KEYS = ("max_episode_steps", "horizon")


def default_max_episode_steps(env_id: str) -> int:
    """The episode length of ``env_id`` with its default config [steps]."""
    return int(json.loads(resolve_spec(env_id, "{}"))["max_episode_steps"])


def with_episode_length(env_id: str, config: dict[str, Any],
                        max_episode_steps: int | None) -> dict[str, Any]:
    """``config`` with ``max_episode_steps`` under the env's length key, unless ``config``
    already sets that key (or no length is given)."""
    if max_episode_steps is None or any(key in config for key in LENGTH_KEYS):
        return config
    resolved = json.loads(resolve_spec(env_id, json.dumps(config)))["config"]
    key = next((k for k in LENGTH_KEYS if k in resolved), None)
    if key is None:
        raise ValueError(f"{env_id} has no episode-length config key ({' or '.join(LENGTH_KEYS)})")
    return {**config, key: int(max_episode_steps)}
