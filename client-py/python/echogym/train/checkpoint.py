"""Checkpoints of a run: finding the latest, loading one, and the trained policy in it.
Written by :meth:`echogym.train.ppo.PPOTrainer.save`."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import torch
from torch import nn

from echogym.train.config import TrainConfig
from echogym.train.networks import build_networks


def latest_checkpoint(path: str | os.PathLike[str]) -> Path:
    """``path`` itself if a file, else ``path/latest.pt``."""
    p = Path(path)
    if p.is_dir():
        p = p / "latest.pt"
    if not p.is_file():
        raise FileNotFoundError(f"no checkpoint at {p}")
    return p


def load_checkpoint(path: str | os.PathLike[str]) -> dict[str, Any]:
    """A checkpoint written by :class:`PPOTrainer` (a plain dict of tensors and numbers)."""
    return torch.load(latest_checkpoint(path), map_location="cpu", weights_only=False)


def load_policy(path: str | os.PathLike[str]) -> tuple[nn.Module, TrainConfig]:
    """The trained actor of a checkpoint (CPU) and the run's config."""
    ckpt = load_checkpoint(path)
    cfg = TrainConfig.from_dict(ckpt["config"])
    actor, _ = build_networks(cfg)
    actor.load_state_dict(ckpt["actor"])
    return actor, cfg
