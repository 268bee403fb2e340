"""Training on echogym: PPO written with torchrl 0.14 (``ClipPPOLoss``, ``GAE``,
``MultiSyncCollector`` worker processes that each attach to the server), Ray scale-out
(:mod:`echogym.train.scale_out`) and learning-curve plots (:mod:`echogym.train.plot`).

Command line: ``python -m echogym.train --help`` (also the ``echogym-train`` script).
Docs: docs/training.md.
"""

from __future__ import annotations

from echogym.train.config import TrainConfig
from echogym.train.ppo import PPOTrainer, evaluate, load_checkpoint, load_policy, zero_policy

__all__ = ["PPOTrainer", "TrainConfig", "evaluate", "load_checkpoint", "load_policy", "zero_policy"]
