"""The networks of a run: the actor and critic a :class:`TrainConfig` describes (sized from
the env's spec, resolved locally without a server), and the zero-action baseline policy."""

from __future__ import annotations

import json
from typing import Any

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.data import Bounded

from echogym._native import resolve_spec
from echogym.train.config import TrainConfig
from echogym.train.envs import default_obs_keys, obs_size
from echogym.train.models import make_actor, make_critic


def action_spec(cfg: TrainConfig) -> Bounded:
    """The env's action bounds as a torchrl spec (one env, no batch)."""
    spec = json.loads(resolve_spec(cfg.env_id, json.dumps(cfg.env_config)))["action"]
    return Bounded(
        low=torch.tensor(spec["low"], dtype=torch.float32),
        high=torch.tensor(spec["high"], dtype=torch.float32),
        shape=(spec["size"],),
        dtype=torch.float32,
    )


def build_networks(cfg: TrainConfig) -> tuple[nn.Module, nn.Module]:
    """The actor and critic of ``cfg`` (on CPU, seeded by ``cfg.seed``)."""
    torch.manual_seed(cfg.seed)
    keys = cfg.obs_keys or default_obs_keys(cfg.env_id, cfg.env_config)
    size = obs_size(cfg.env_id, cfg.env_config, keys)
    actor = make_actor(size, action_spec(cfg), cfg.hidden, cfg.activation, cfg.log_std_init)
    critic = make_critic(size, cfg.hidden, cfg.activation)
    return actor, critic


class _ZeroPolicy(TensorDictModule):
    """Always the zero action (the ``zero`` baseline)."""

    def __init__(self, action_size: int) -> None:
        super().__init__(nn.Identity(), in_keys=["observation"], out_keys=["action"])
        self.action_size = action_size

    def forward(self, tensordict: TensorDictBase, *args: Any, **kwargs: Any) -> TensorDictBase:
        obs = tensordict.get("observation")
        tensordict.set("action", torch.zeros(*obs.shape[:-1], self.action_size))
        return tensordict


def zero_policy(cfg: TrainConfig) -> nn.Module:
    """A policy that always sends the zero action."""
    return _ZeroPolicy(action_spec(cfg).shape[-1])
