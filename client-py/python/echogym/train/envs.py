"""The env a PPO worker steps: :class:`echogym.torchrl.EchoEnv` (a batch of server-side
envs) with the observation fields concatenated into one ``"observation"`` vector, the
episode return and length tracked, and the info keys the trainer reports on.

Factories are ``functools.partial`` of module-level functions, so they pickle into
collector worker processes (spawned) and Ray actors; each worker builds its own env and
takes its own lease on first use.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable, Sequence
from typing import Any

from torchrl.envs import CatTensors, Compose, EnvBase, RewardSum, StepCounter, TransformedEnv

from echogym._native import resolve_spec
from echogym.torchrl import EchoEnv

#: Info keys reported (as episode-end values) when the env declares them.
REPORTED_INFO = ("is_success", "contact_force", "in_contact", "progress", "cube_to_goal")


def default_obs_keys(env_id: str, env_config: dict[str, Any]) -> list[str]:
    """Every 1-D float observation field (no camera images, no particle state)."""
    spec = json.loads(resolve_spec(env_id, json.dumps(env_config)))
    return [
        f["name"]
        for f in spec["observation"]
        if f["dtype"] == "float32" and len(f["shape"]) == 1
    ]


def obs_size(env_id: str, env_config: dict[str, Any], obs_keys: Sequence[str]) -> int:
    """Length of the concatenated ``"observation"`` vector."""
    spec = json.loads(resolve_spec(env_id, json.dumps(env_config)))
    sizes = {f["name"]: int(f["shape"][0]) if f["shape"] else 1 for f in spec["observation"]}
    unknown = [k for k in obs_keys if k not in sizes]
    if unknown:
        raise ValueError(f"{env_id} has no observation fields {unknown}")
    return sum(sizes[k] for k in obs_keys)


def info_keys_for(env_id: str, env_config: dict[str, Any]) -> list[str]:
    """The reported info keys this env declares."""
    spec = json.loads(resolve_spec(env_id, json.dumps(env_config)))
    return [k for k in REPORTED_INFO if k in spec["info_keys"]]


def build_env(
    env_id: str,
    num_envs: int,
    env_config: dict[str, Any],
    obs_keys: Sequence[str],
    server: str | None = None,
    copy_observations: bool = False,
) -> EnvBase:
    """One worker's env: ``num_envs`` server-side envs behind torchrl transforms."""
    base = EchoEnv(
        env_id,
        num_envs,
        server=server,
        copy_observations=copy_observations,
        info_keys=info_keys_for(env_id, env_config),
        **env_config,
    )
    return TransformedEnv(
        base,
        Compose(
            CatTensors(list(obs_keys), "observation", del_keys=True),
            RewardSum(),
            StepCounter(),
        ),
    )


def env_factory(
    env_id: str,
    num_envs: int,
    env_config: dict[str, Any],
    obs_keys: Sequence[str],
    server: str | None = None,
) -> Callable[[], EnvBase]:
    """A picklable factory of :func:`build_env` (zero-copy: collectors copy every step)."""
    return functools.partial(build_env, env_id, num_envs, dict(env_config), list(obs_keys), server)
