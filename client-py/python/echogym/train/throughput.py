"""Is the training stack the bottleneck? ``python -m echogym.train.throughput`` measures,
against one server, env-steps/s of

- ``raw``: one process stepping all ``workers × envs_per_worker`` envs through the
  gymnasium vector env (zero-copy, same-step autoreset: the envs benchmark's method),
  with actions drawn from the distribution the collector's actor samples at the start of
  training (``N(0, exp(log_std_init))`` per element, clipped to the bounds by the server;
  ``--raw-actions uniform`` gives the envs benchmark's ±0.3 instead), and
- ``collector``: torchrl's ``MultiSyncCollector`` with ``workers`` worker processes of
  ``envs_per_worker`` envs each, the default PPO actor choosing the actions through its
  collection path (:class:`echogym.train.models.GaussianSampler`, as the trainer collects;
  inference, the env's Python side and the collector's copies included; no PPO update),

alternately (``--repeats`` pairs, raw then collector, both kept alive in between), and
prints their ratios and the medians. Both use the same server (``--threads`` worker threads) and the
same number of envs, so the ratio is what the collector costs on top of the envs. The
actions matter: the scan's physics costs ≈ 15–30 % more server CPU per step under the
actor's ``N(0, 1)`` actions than under ±0.3 (docs/results/benchmarks.md, "Training"), so
a raw run with other actions than the collector's measures a different workload.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from typing import Any

import numpy as np
import torch

from echogym.client import connect
from echogym.gym_vector import EchoVectorEnv
from echogym.train.config import TrainConfig
from echogym.train.models import GaussianSampler
from echogym.train.envs import default_obs_keys, env_factory
from echogym.train.networks import build_networks
from echogym.train.timing import timed_collection


class _RawStepper:
    """One vector env of ``num_envs`` envs stepped with 16 pre-drawn action batches:
    ``N(0, action_std)`` (the default actor's initial distribution), or uniform in ±0.3
    when ``action_std`` is ``None``."""

    def __init__(self, env_id: str, num_envs: int, config: dict[str, Any], server: str,
                 action_std: float | None) -> None:
        self.num_envs = num_envs
        self.env = EchoVectorEnv(env_id, num_envs, server=server, **config)
        rng = np.random.default_rng(0)
        shape = (num_envs, self.env.single_action_space.shape[0])
        self.actions = [
            (rng.uniform(-0.3, 0.3, size=shape) if action_std is None
             else rng.normal(0.0, action_std, size=shape)).astype(np.float32)
            for _ in range(16)
        ]
        self.env.reset(seed=0)
        for i in range(20):
            self.env.step(self.actions[i % 16])

    def rate(self, seconds: float) -> float:
        """Env-steps/s over ``seconds``."""
        steps = 0
        start = time.monotonic()
        while time.monotonic() - start < seconds:
            self.env.step(self.actions[steps % 16])
            steps += 1
        return steps * self.num_envs / (time.monotonic() - start)

    def close(self) -> None:
        self.env.close()


def raw_rate(env_id: str, num_envs: int, config: dict[str, Any], server: str,
             seconds: float, action_std: float | None = None) -> float:
    """Env-steps/s of one vector env of ``num_envs`` envs: actions ``N(0, action_std)``
    (the default actor's initial distribution), or uniform in ±0.3 when ``None``."""
    stepper = _RawStepper(env_id, num_envs, config, server, action_std)
    try:
        return stepper.rate(seconds)
    finally:
        stepper.close()


def _collector(env_id: str, workers: int, envs_per_worker: int, config: dict[str, Any],
               server: str, batches: int, steps_per_batch: int = 64) -> Any:
    """A ``MultiSyncCollector`` of ``batches`` batches driven by the default PPO actor."""
    from torchrl.collectors import MultiSyncCollector

    cfg = TrainConfig(env_id=env_id, env_config=config)
    actor, _ = build_networks(cfg)
    make_env = env_factory(env_id, envs_per_worker, config, default_obs_keys(env_id, config),
                           server)
    frames = workers * envs_per_worker * steps_per_batch
    return MultiSyncCollector([make_env] * workers, GaussianSampler(actor),
                              frames_per_batch=frames, total_frames=frames * batches,
                              device="cpu")


def collector_rate(env_id: str, workers: int, envs_per_worker: int, config: dict[str, Any],
                   server: str, batches: int, steps_per_batch: int = 64) -> float:
    """Env-steps/s of a ``MultiSyncCollector`` driven by the default PPO actor."""
    warmup = 2
    collector = _collector(env_id, workers, envs_per_worker, config, server,
                           batches + warmup, steps_per_batch)
    count, elapsed = timed_collection(collector, warmup)
    return count / elapsed


def measure(env_id: str, workers: int, envs_per_worker: int, config: dict[str, Any],
            server: str, seconds: float, batches: int, repeats: int,
            report: bool = True, raw_actions: str = "policy") -> dict[str, Any]:
    """``repeats`` × (raw for ``seconds``, then ``batches`` collector batches) against
    ``server``: every run and the medians.

    The raw vector env and the collector (its workers spawned and warmed up once) are
    built first and stay alive; each repeat times a raw slice and the collector batches
    right after it, so each ratio compares two runs seconds apart (on a shared machine
    the load changes between runs far apart). ``raw_actions``: ``"policy"`` (the
    actor's initial action distribution, what the collector steps) or ``"uniform"``.
    """
    total = workers * envs_per_worker
    if raw_actions not in ("policy", "uniform"):
        raise ValueError(f"raw_actions must be 'policy' or 'uniform', not {raw_actions!r}")
    action_std = (math.exp(TrainConfig(env_id=env_id, env_config=config).log_std_init)
                  if raw_actions == "policy" else None)
    warmup = 2
    collector = _collector(env_id, workers, envs_per_worker, config, server,
                           warmup + repeats * batches)
    stepper = None
    runs = []
    try:
        batch_iter = iter(collector)
        for _ in range(warmup):
            next(batch_iter)
        stepper = _RawStepper(env_id, total, config, server, action_std)
        for repeat in range(repeats):
            raw = stepper.rate(seconds)
            frames = 0
            start = time.monotonic()
            for _ in range(batches):
                frames += next(batch_iter).numel()
            coll = frames / (time.monotonic() - start)
            row = {"repeat": repeat, "raw_env_steps_per_s": round(raw, 1),
                   "collector_env_steps_per_s": round(coll, 1), "ratio": round(coll / raw, 3)}
            runs.append(row)
            if report:
                print(json.dumps(row), flush=True)
    finally:
        collector.shutdown()
        if stepper is not None:
            stepper.close()
    median = {
        key: float(np.median([r[key] for r in runs]))
        for key in ("raw_env_steps_per_s", "collector_env_steps_per_s", "ratio")
    }
    return {"env_id": env_id, "workers": workers, "envs_per_worker": envs_per_worker,
            "raw_actions": raw_actions, "runs": runs, "median": median}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m echogym.train.throughput",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--env-id", default="echogym/PushCube-v0")
    parser.add_argument("--env-config", type=json.loads, default={})
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--envs-per-worker", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=3.0,
                        help="raw measurement time per repeat")
    parser.add_argument("--batches", type=int, default=8,
                        help="collector batches per repeat (64 steps of every env each)")
    parser.add_argument("--repeats", type=int, default=5,
                        help="(raw, collector) pairs, measured back to back")
    parser.add_argument("--server", default=None,
                        help="a running server (default: a private one with --threads)")
    parser.add_argument("--threads", type=int, default=0, help="private server's threads")
    parser.add_argument("--raw-actions", choices=("policy", "uniform"), default="policy",
                        help="raw run's actions: the actor's initial N(0, exp(log_std_init)) "
                             "(default) or the envs benchmark's uniform ±0.3")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)

    server = args.server
    private = None
    if server is None:
        import subprocess

        server = f"throughput-{os.getpid()}"
        private = subprocess.Popen(
            [sys.executable, "-m", "echogym", "serve", "--name", server, "--log", "warn",
             "--threads", str(args.threads), "--exit-with-parent", str(os.getpid())],
            stdin=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 30
        while True:
            try:
                connect(server)
                break
            except Exception:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.05)
    try:
        result = measure(args.env_id, args.workers, args.envs_per_worker, args.env_config,
                         server, args.seconds, args.batches, args.repeats,
                         raw_actions=args.raw_actions)
        del result["runs"]
        print(json.dumps(result), flush=True)
    finally:
        if private is not None:
            private.terminate()
            private.wait(timeout=15)
    return 0


if __name__ == "__main__":
    sys.exit(main())
