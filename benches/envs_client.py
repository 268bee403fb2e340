"""The client side of `benches/run envs`: does the training stack keep up with the server?

- `collector_ratio`: torchrl's `MultiSyncCollector` (2 worker processes, the default PPO
  actor through its collection path) against the raw vector env over the same envs
  stepped with the actor's initial action distribution, on one 2-thread server
  (`echogym.train.throughput`): UltrasoundScan-v0 at 500 Hz, episodes ending only at the
  horizon, 16 and 64 envs per worker. The headline is the worse ratio.
- `async_gain`: envpool-style asynchronous batches against the synchronous vector env,
  with heterogeneous step costs and a policy to overlap: UltrasoundScan-v0 at 500 Hz with
  the seed's early termination (an episode ends every few steps under random actions, and
  a reset redraws and rebuilds the torso: ≈ 10–30× a step), 32 envs; the client runs the
  default PPO actor's forward pass on every batch. Sync: one `EchoVectorEnv` of 32.
  Async: `EchoAsyncVectorEnv` of 32 envs, `recv` of the first 16 ready, groups of 8. The
  gain is async env-steps/s over sync. The server is the envs suite's (1 worker thread,
  pinned to one core; this process on the other).
"""

from __future__ import annotations

import statistics
import time
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict

from echogym.gym_async import EchoAsyncVectorEnv
from echogym.gym_vector import EchoVectorEnv
from echogym.train import throughput
from echogym.train.config import TrainConfig
from echogym.train.envs import default_obs_keys
from echogym.train.models import GaussianSampler
from echogym.train.networks import build_networks

SCAN = "echogym/UltrasoundScan-v0"
COLLECTOR_CONFIG: dict[str, Any] = {"task": {"early_termination": False}}
ASYNC_CONFIG: dict[str, Any] = {}  # the seed's early termination: heterogeneous steps
ASYNC_ENVS, ASYNC_BATCH, ASYNC_GROUP = 32, 16, 8


def collector_ratio(server: str, seconds: float, repeats: int) -> dict[str, Any]:
    """Collector / raw env-steps/s at 16 and 64 envs per worker; `ratio` the worse."""
    torch.set_num_threads(1)
    by_batch = {}
    for per_worker in (16, 64):
        by_batch[per_worker] = throughput.measure(
            SCAN, 2, per_worker, COLLECTOR_CONFIG, server, seconds, batches=6,
            repeats=repeats, report=False)
    return {"by_envs_per_worker": by_batch,
            "ratio": min(r["median"]["ratio"] for r in by_batch.values())}


class _Policy:
    """The default PPO actor's collection path on the concatenated vector fields."""

    def __init__(self, env_id: str, config: dict[str, Any]) -> None:
        actor, _ = build_networks(TrainConfig(env_id=env_id, env_config=config))
        self.sampler = GaussianSampler(actor)
        self.keys = default_obs_keys(env_id, config)

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        observation = torch.from_numpy(
            np.concatenate([obs[k] for k in self.keys], axis=-1, dtype=np.float32))
        with torch.no_grad():
            td = self.sampler(TensorDict({"observation": observation}, [len(observation)]))
        return td["action"].numpy()


def _sync_rate(server: str, policy: _Policy, seconds: float) -> float:
    envs = EchoVectorEnv(SCAN, ASYNC_ENVS, server=server, **ASYNC_CONFIG)
    obs, _ = envs.reset(seed=0)
    for _ in range(5):
        obs, *_ = envs.step(policy(obs))
    steps, started = 0, time.perf_counter()
    while time.perf_counter() - started < seconds:
        obs, *_ = envs.step(policy(obs))
        steps += ASYNC_ENVS
    elapsed = time.perf_counter() - started
    envs.close()
    return steps / elapsed


def _async_rate(server: str, policy: _Policy, seconds: float) -> float:
    envs = EchoAsyncVectorEnv(SCAN, ASYNC_ENVS, ASYNC_BATCH, group_size=ASYNC_GROUP,
                              server=server, **ASYNC_CONFIG)
    envs.async_reset(seed=0)
    for _ in range(10):
        obs, _, _, _, info = envs.recv()
        envs.send(policy(obs), info["env_id"])
    steps, started = 0, time.perf_counter()
    while time.perf_counter() - started < seconds:
        obs, _, _, _, info = envs.recv()
        envs.send(policy(obs), info["env_id"])
        steps += len(info["env_id"])
    elapsed = time.perf_counter() - started
    envs.close()
    return steps / elapsed


def async_gain(server: str, seconds: float, repeats: int) -> dict[str, Any]:
    """Sync and async env-steps/s (alternating, `repeats` each) and their ratio."""
    torch.set_num_threads(1)
    policy = _Policy(SCAN, ASYNC_CONFIG)
    sync, asyn = [], []
    for _ in range(repeats):
        sync.append(_sync_rate(server, policy, seconds))
        asyn.append(_async_rate(server, policy, seconds))
    gain = statistics.median(asyn) / statistics.median(sync)
    return {"sync": {"median": statistics.median(sync), "runs": sync},
            "async": {"median": statistics.median(asyn), "runs": asyn}, "gain": gain}


def table_lines(collector: dict[str, Any] | None, gain: dict[str, Any] | None) -> list[str]:
    """Markdown lines for the suite's table."""
    lines: list[str] = []
    if collector is not None:
        lines += ["", "| torchrl collector vs raw (2 workers, 2-thread server, scan 500 Hz, "
                  "raw with the actor's N(0, 1) actions) "
                  "| raw env-steps/s | collector env-steps/s | ratio | runs (ratio) |",
                  "|---|---:|---:|---:|---|"]
        for per_worker, r in collector["by_envs_per_worker"].items():
            m = r["median"]
            ratios = ", ".join(f"{x:.2f}" for x in (run["ratio"] for run in r["runs"]))
            lines.append(
                f"| 2 × {per_worker} envs | {m['raw_env_steps_per_s']:,.0f} | "
                f"{m['collector_env_steps_per_s']:,.0f} | {m['ratio']:.2f} | {ratios} |")
        lines.append(f"\nCollector ratio (the worse of 16 and 64 per worker): "
                     f"{collector['ratio']:.2f} (target ≥ 0.85: "
                     f"{'met' if collector['ratio'] >= 0.85 else 'MISSED'}).")
    if gain is not None:
        lines += [
            "",
            f"Async batches (scan 500 Hz with early termination, {ASYNC_ENVS} envs, policy "
            f"forward on each batch): sync {gain['sync']['median']:,.0f} env-steps/s "
            f"(runs {', '.join(f'{x:,.0f}' for x in gain['sync']['runs'])}), async first "
            f"{ASYNC_BATCH} of {ASYNC_ENVS} in groups of {ASYNC_GROUP} "
            f"{gain['async']['median']:,.0f} (runs "
            f"{', '.join(f'{x:,.0f}' for x in gain['async']['runs'])}): gain "
            f"{gain['gain']:.2f}×.",
        ]
    return lines
