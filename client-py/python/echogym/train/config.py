"""`TrainConfig`: every setting of a PPO run, its defaults, and the command line that sets
them (``python -m echogym.train --help``). The resolved config is saved in every
checkpoint and in ``LOGDIR/config.json``, so a run can be reproduced and resumed."""

from __future__ import annotations

import argparse
import dataclasses
import json
from dataclasses import dataclass, field
from typing import Any


@dataclass
class TrainConfig:
    """A PPO run. Frame counts are env steps summed over every env."""

    env_id: str = "echogym/PushCube-v0"
    env_config: dict[str, Any] = field(default_factory=dict)
    """Env config passed to every env (JSON object; unknown keys are refused by the server)."""
    obs_keys: list[str] | None = None
    """Observation fields concatenated into the policy's input (default: every 1-D float field)."""
    server: str | None = None
    """Server name (default ``$ECHOGYM_SERVER``/``default``; a private server is started if none runs)."""
    num_workers: int = 2
    """Collector worker processes, each attaching to the server with its own lease."""
    envs_per_worker: int = 16
    frames_per_batch: int = 4096
    total_frames: int = 1_000_000
    epochs: int = 10
    minibatch_size: int = 512
    lr: float = 3e-4
    lr_schedule: str = "constant"
    """``constant`` or ``linear`` (to 0 at ``total_frames``)."""
    gamma: float = 0.99
    lmbda: float = 0.95
    clip_epsilon: float = 0.2
    entropy_coef: float = 0.0
    critic_coef: float = 0.5
    max_grad_norm: float = 0.5
    hidden: list[int] = field(default_factory=lambda: [256, 128])
    """Hidden layer widths of both actor and critic (the seed's [256, 128])."""
    activation: str = "tanh"
    log_std_init: float = 0.0
    normalize_observations: bool = True
    success_bonus: float = 0.0
    """Reward added on steps that terminate with ``is_success`` (0: off). See docs/training.md."""
    seed: int = 0
    device: str = "auto"
    """Where the PPO update runs: ``auto`` (CUDA when present), ``cpu``, ``cuda``, ``cuda:1``."""
    logdir: str = "runs/ppo"
    checkpoint_every: int = 100_000
    """Frames between checkpoints (one is always written at the end)."""
    eval_every: int = 0
    """Frames between evaluations during training (0: only at the end)."""
    eval_episodes: int = 32
    eval_envs: int = 16
    ray_servers: list[str] | None = None
    """Collect through Ray: one collector per named server, pinned to the server's node
    (``num_workers`` worker processes each; see :mod:`echogym.train.scale_out`)."""
    ray_address: str | None = None
    """Ray cluster to join (``auto``, ``HOST:6379``); default: start a local cluster."""
    ray_cpus_per_collector: float = 1.0
    progress: bool = True
    threads: int = 1
    """torch threads of the trainer process (the envs run in the server and the workers)."""

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), indent=2)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "TrainConfig":
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ValueError(f"unknown training settings {unknown}")
        return cls(**data)


def _bool(text: str) -> bool:
    if text.lower() in ("1", "true", "yes", "on"):
        return True
    if text.lower() in ("0", "false", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"expected a boolean, got {text!r}")


def build_parser() -> argparse.ArgumentParser:
    """The ``echogym-train`` / ``python -m echogym.train`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="python -m echogym.train",
        description="Train a PPO policy (torchrl) on an echogym env with multi-process collectors.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    defaults = TrainConfig()
    parser.add_argument("--config", help="JSON file of settings (flags override it)")
    parser.add_argument("--resume", metavar="PATH",
                        help="checkpoint file, or a logdir (its latest checkpoint), to continue from")
    parser.add_argument("--eval-only", metavar="CHECKPOINT",
                        help="evaluate a checkpoint (or 'zero' / 'initial' baselines) and exit")
    for f in dataclasses.fields(TrainConfig):
        flag = "--" + f.name.replace("_", "-")
        default = getattr(defaults, f.name)
        helptext = (f.metadata.get("help") or "")
        if f.name == "env_config":
            parser.add_argument(flag, type=json.loads, default=None,
                                help="env config as a JSON object, e.g. '{\"robot\": \"ur5e\"}'")
        elif f.name in ("obs_keys", "ray_servers"):
            parser.add_argument(flag, nargs="+", default=None,
                                help="observation fields" if f.name == "obs_keys" else "server names")
        elif f.name == "hidden":
            parser.add_argument(flag, type=int, nargs="+", default=None,
                                help=f"hidden widths (default {default})")
        elif isinstance(default, bool):
            parser.add_argument(flag, type=_bool, default=None, help=f"(default {default})")
        elif isinstance(default, (int, float, str)) or default is None:
            kind = type(default) if default is not None else str
            parser.add_argument(flag, type=kind, default=None, help=helptext or f"(default {default})")
    return parser


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    """Defaults ← ``--config`` file ← flags."""
    data: dict[str, Any] = {}
    if args.config:
        with open(args.config) as fh:
            data.update(json.load(fh))
    for f in dataclasses.fields(TrainConfig):
        value = getattr(args, f.name, None)
        if value is not None:
            data[f.name] = value
    return TrainConfig.from_dict(data)
