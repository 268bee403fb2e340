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
    eval_video: int = 256
    """Width and height [px] of the video of one evaluation episode written at each
    evaluation (``LOGDIR/videos/``; 0: none)."""
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


#: Help of each setting on the command line (the default is appended).
HELP = {
    "env_id": "echogym env id",
    "env_config": "env config as a JSON object, e.g. '{\"robot\": \"ur5e\"}'",
    "obs_keys": "observation fields concatenated into the policy input (default: every 1-D float field)",
    "server": "server name (default $ECHOGYM_SERVER or 'default'; started privately if none runs)",
    "num_workers": "collector worker processes, each with its own lease (0: collect in-process; "
                   "with --ray-servers: workers per server)",
    "envs_per_worker": "server-side envs stepped by each worker",
    "frames_per_batch": "env steps per PPO iteration, summed over all envs",
    "total_frames": "env steps of the whole run (a resumed run continues up to it)",
    "epochs": "passes over each batch",
    "minibatch_size": "transitions per gradient step",
    "lr": "Adam learning rate",
    "lr_schedule": "'constant' or 'linear' (to 0 at --total-frames)",
    "gamma": "discount",
    "lmbda": "GAE lambda",
    "clip_epsilon": "PPO clip range",
    "entropy_coef": "entropy bonus coefficient (0: off)",
    "critic_coef": "value loss coefficient",
    "max_grad_norm": "gradient clipping norm",
    "hidden": "hidden layer widths of actor and critic (the seed's 256 128)",
    "activation": "tanh, relu or elu",
    "log_std_init": "initial log standard deviation of the Gaussian policy",
    "normalize_observations": "running mean/std observation normalisation",
    "success_bonus": "reward added on steps that terminate with is_success (docs/training.md)",
    "seed": "seed of the networks, the envs and the evaluation episodes",
    "device": "where the PPO update runs: auto (CUDA when present), cpu, cuda, cuda:1",
    "logdir": "run directory: CSV, TensorBoard events, checkpoints, summary",
    "checkpoint_every": "env steps between checkpoints (one is always written at the end)",
    "eval_every": "env steps between evaluations (0: only at the end)",
    "eval_episodes": "deterministic evaluation episodes (0: none)",
    "eval_envs": "envs the evaluation runs on",
    "eval_video": "size [px] of the evaluation episode's video, LOGDIR/videos/eval-FRAMES.mp4 (0: none)",
    "ray_servers": "collect through Ray: one collector per named server, on that server's node",
    "ray_address": "Ray cluster to join (auto, HOST:6379); default: start a local cluster",
    "ray_cpus_per_collector": "Ray CPUs each remote collector asks for",
    "progress": "show the progress bar (drawn only when stderr is a terminal)",
    "threads": "torch threads of the trainer process",
}


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
        text = HELP.get(f.name, "")
        if default is not None:
            text += f" (default: {json.dumps(default)})"
        if f.name == "env_config":
            parser.add_argument(flag, type=json.loads, default=None, help=text)
        elif f.name in ("obs_keys", "ray_servers"):
            parser.add_argument(flag, nargs="+", default=None, help=text)
        elif f.name == "hidden":
            parser.add_argument(flag, type=int, nargs="+", default=None, help=text)
        elif isinstance(default, bool):
            parser.add_argument(flag, type=_bool, default=None, help=text)
        elif f.name == "ray_cpus_per_collector" or isinstance(default, float):
            parser.add_argument(flag, type=float, default=None, help=text)
        elif isinstance(default, int):
            parser.add_argument(flag, type=int, default=None, help=text)
        else:
            choices = {"lr_schedule": ["constant", "linear"],
                       "activation": ["tanh", "relu", "elu"]}.get(f.name)
            parser.add_argument(flag, type=str, default=None, help=text, choices=choices)
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
