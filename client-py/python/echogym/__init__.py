"""echogym: robot-assisted ultrasound simulation served over zero-copy shared memory.

Import this package to register every echogym env with gymnasium::

    import gymnasium, echogym
    env = gymnasium.make("echogym/Null-v0")
    envs = gymnasium.make_vec("echogym/Null-v0", num_envs=64,
                              vectorization_mode="vector_entry_point")

Each id is registered with its default episode length as ``max_episode_steps``
(:mod:`echogym.episode`). For torchrl use :class:`echogym.torchrl.EchoEnv`, for
stable-baselines3 :class:`echogym.sb3.SB3VecEnv` (import them from their modules: torch is
optional). The applications (demo, figures, plots, training) are :mod:`echogym.apps` and
:mod:`echogym.train`; importing ``echogym`` imports neither.
"""

from __future__ import annotations

import gymnasium

from echogym._native import PROTOCOL_VERSION, __version__, registered_envs
from echogym.calibration import load_calibration
from echogym.client import Client, connect
from echogym.episode import default_max_episode_steps
from echogym import errors
from echogym.errors import *  # noqa: F403 (the exception tree, listed in errors.__all__)
from echogym.gym_env import EchoEnv
from echogym.gym_vector import EchoVectorEnv


def _register_all() -> None:
    for env_id, _description in registered_envs():
        if env_id in gymnasium.registry:
            continue
        gymnasium.register(
            id=env_id,
            entry_point="echogym.gym_env:EchoEnv",
            vector_entry_point="echogym.gym_vector:EchoVectorEnv",
            max_episode_steps=default_max_episode_steps(env_id),
            kwargs={"env_id": env_id},
        )


_register_all()

__all__ = [
    "PROTOCOL_VERSION",
    "Client",
    "EchoEnv",
    "EchoVectorEnv",
    "__version__",
    "connect",
    "load_calibration",
    "registered_envs",
    *errors.__all__,
]
