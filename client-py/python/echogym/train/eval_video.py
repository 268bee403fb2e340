"""Evaluation videos: one deterministic episode of the policy on one fresh env, seen by the
smooth-shaded viewing camera (:data:`echogym.render.VIEW_CAMERA`), written as an mp4 next
to the run's logs (``LOGDIR/videos/eval-<frames>.mp4``) at each evaluation.

The camera renders only the steps that become frames (``every``), and only on this
one-env rollout, so the evaluation's own envs and the collectors pay nothing."""

from __future__ import annotations

import json
from pathlib import Path

import torch
from torch import nn
from torchrl.envs import ExplorationType, set_exploration_type

from echogym._native import resolve_spec
from echogym.render import VIEW_CAMERA
from echogym.train.config import TrainConfig
from echogym.train.envs import build_env, default_obs_keys
from echogym.video import write_mp4

__all__ = ["VIDEO_FPS", "record_episode"]

#: Frames per second of the videos.
VIDEO_FPS = 25
_CAMERA = "eval_video"


def record_episode(policy: nn.Module, cfg: TrainConfig, path: Path, seed: int | None = None) -> Path:
    """Run one episode of ``policy`` (deterministic actions) and write it to ``path``."""
    size = cfg.eval_video
    keys = cfg.obs_keys or default_obs_keys(cfg.env_id, cfg.env_config)
    dt = json.loads(resolve_spec(cfg.env_id, json.dumps(cfg.env_config)))["dt_s"]
    every = max(1, round(1.0 / (VIDEO_FPS * dt)))
    camera = {**VIEW_CAMERA, "name": _CAMERA, "width": size, "height": size, "every": every}
    config = {**cfg.env_config, "cameras": [*cfg.env_config.get("cameras", []), camera]}
    server = cfg.server or (cfg.ray_servers[0] if cfg.ray_servers else None)
    env = build_env(cfg.env_id, 1, config, keys, server, copy_observations=True)
    policy = policy.to("cpu")
    key = f"{_CAMERA}_rgb"
    try:
        env.set_seed(cfg.seed + 1_000_003 if seed is None else seed)
        td = env.reset()
        frames = [td[key][0].numpy().copy()]
        step = 0
        while True:
            with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
                td = policy(td)
            td, root = env.step_and_maybe_reset(td)
            nxt = td["next"]
            step += 1
            if step % every == 0:
                frames.append(nxt[key][0].numpy().copy())
            if bool(nxt["done"].any()):
                break
            td = root
    finally:
        env.close()
    return write_mp4(frames, path, 1.0 / (every * dt))
