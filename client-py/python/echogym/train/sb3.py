"""The stable-baselines3 adapter is part of the library, :mod:`echogym.sb3`; this module
keeps ``from echogym.train.sb3 import SB3VecEnv`` (examples/sb3_ppo.py, scripts) working."""

from echogym.sb3 import SB3VecEnv

__all__ = ["SB3VecEnv"]
