"""Deterministic evaluation of a policy on fresh envs: per-episode and mean return,
length, success and, for envs with a contact force, the share of the sweep in contact and
within ±1 N of the target."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import torch
from torch import nn
from torchrl.envs import ExplorationType, set_exploration_type

from echogym._native import resolve_spec
from echogym.train.config import TrainConfig
from echogym.train.envs import build_env, default_obs_keys


def evaluate(
    policy: nn.Module,
    cfg: TrainConfig,
    episodes: int | None = None,
    num_envs: int | None = None,
    seed: int | None = None,
) -> dict[str, Any]:
    """Run ``episodes`` episodes with deterministic actions; per-episode and mean metrics.

    Every env runs the same number of episodes (so short episodes are not over-counted).
    Metrics: ``return``, ``length``, ``success`` (``is_success`` at the episode's end) and,
    for envs with a contact force, ``contact_share`` (steps in contact / horizon) and
    ``force_band_share`` (steps in contact with the force within ±1 N of the target /
    horizon: the share of the sweep spent holding the force).
    """
    episodes = episodes or cfg.eval_episodes
    num_envs = min(num_envs or cfg.eval_envs, episodes)
    per_env = math.ceil(episodes / num_envs)
    keys = cfg.obs_keys or default_obs_keys(cfg.env_id, cfg.env_config)
    resolved = json.loads(resolve_spec(cfg.env_id, json.dumps(cfg.env_config)))["config"]
    horizon = int(resolved["horizon"])
    target_force = float(resolved.get("task", {}).get("target_force", 5.0))
    # With Ray the driver evaluates on `server`, by default the first Ray server (which
    # must then run on the driver's node).
    server = cfg.server or (cfg.ray_servers[0] if cfg.ray_servers else None)
    env = build_env(cfg.env_id, num_envs, cfg.env_config, keys, server, copy_observations=True)
    policy = policy.to("cpu")
    records: list[dict[str, float]] = []
    try:
        env.set_seed(cfg.seed + 1_000_003 if seed is None else seed)
        td = env.reset()
        counts = np.zeros(num_envs, dtype=int)
        in_contact = np.zeros(num_envs)
        in_band = np.zeros(num_envs)
        has_force = "contact_force" in td.keys()
        while (counts < per_env).any():
            with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
                td = policy(td)
            td, root = env.step_and_maybe_reset(td)
            nxt = td["next"]
            if has_force:
                contact = nxt["in_contact"].numpy() > 0.5
                force_ok = np.abs(nxt["contact_force"].numpy() - target_force) <= 1.0
                in_contact += contact
                in_band += contact & force_ok
            done = nxt["done"].reshape(num_envs).numpy()
            for i in np.flatnonzero(done):
                if counts[i] < per_env:
                    record = {
                        "return": float(nxt["episode_reward"][i, 0]),
                        "length": int(nxt["step_count"][i, 0]),
                    }
                    if "is_success" in nxt.keys():
                        record["success"] = float(nxt["is_success"][i] > 0.5)
                    if has_force:
                        record["contact_share"] = in_contact[i] / horizon
                        record["force_band_share"] = in_band[i] / horizon
                    records.append(record)
                    counts[i] += 1
                in_contact[i] = 0.0
                in_band[i] = 0.0
            td = root
    finally:
        env.close()
    records = records[:episodes]
    summary: dict[str, Any] = {"episodes": len(records)}
    for key in records[0]:
        values = np.array([r[key] for r in records], dtype=float)
        summary[key + "_mean"] = float(values.mean())
        summary[key + "_std"] = float(values.std())
    summary["per_episode"] = records
    return summary
