"""echogym: robot-assisted ultrasound simulation served over zero-copy shared memory.

Import this package to register every echogym env with gymnasium::

    import gymnasium, echogym
    env = gymnasium.make("echogym/Null-v0")
    envs = gymnasium.make_vec("echogym/Null-v0", num_envs=64,
                              vectorization_mode="vector_entry_point")

For torchrl use :class:`echogym.torchrl.EchoEnv` (imported lazily: torch is optional).
"""

from __future__ import annotations

import gymnasium

from echogym._native import PROTOCOL_VERSION, __version__, registered_envs
from echogym.calibration import load_calibration
from echogym.client import Client, connect
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
