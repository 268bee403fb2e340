"""Training on echogym, an application of the library: PPO written with torchrl 0.14
(``ClipPPOLoss``, ``GAE``, ``MultiSyncCollector`` worker processes that each attach to the
server), Ray scale-out (:mod:`echogym.train.scale_out`) and learning-curve plots
(:mod:`echogym.train.plot`). Needs ``pip install 'echogym[train]'`` (Ray: ``[ray]``).

Modules, each depending only on those before it: ``config`` (settings, command line) →
``models`` (networks), ``envs`` (the worker's env) → ``networks`` (a run's actor and
critic) → ``checkpoint``, ``evaluation``, ``timing`` → ``scale_out``, ``throughput`` →
``ppo`` (the trainer) → ``cli``.

Command line: ``python -m echogym.train --help`` (also the ``echogym-train`` script).
Docs: docs/training.md.
"""

from __future__ import annotations

from echogym.train.checkpoint import load_checkpoint, load_policy
from echogym.train.config import TrainConfig
from echogym.train.evaluation import evaluate
from echogym.train.networks import zero_policy
from echogym.train.ppo import PPOTrainer

__all__ = ["PPOTrainer", "TrainConfig", "evaluate", "load_checkpoint", "load_policy", "zero_policy"]
