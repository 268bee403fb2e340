"""PPO on echogym with torchrl 0.14: ``ClipPPOLoss``, ``GAE``, and a
``MultiSyncCollector`` whose worker processes each attach to the server and step a batch
of server-side envs (or any collector a caller builds, e.g. Ray's, see
:mod:`echogym.train.scale_out`).

One iteration: the collector returns ``num_workers × envs_per_worker × T`` transitions
(time last, as GAE wants) → advantages → ``epochs`` passes of shuffled minibatches →
the observation normaliser folds in the batch → the new weights (normaliser included)
go to the workers. The first batch of a fresh run only seeds the normaliser: its actions
were drawn by a policy that saw unnormalised observations.

Logs (``LOGDIR``): ``progress.csv`` and TensorBoard events per iteration, ``eval.csv`` and
``videos/eval-FRAMES.mp4`` (one evaluation episode) per evaluation,
``checkpoints/frames_*.pt`` and ``latest.pt`` (weights, normaliser, optimiser, counters,
RNG, config), ``config.json``, ``summary.json`` at the end.
"""

from __future__ import annotations

import copy
import csv
import json
import math
import os
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase
from torch import nn
from torchrl.collectors import Collector, MultiSyncCollector
from torchrl.objectives import ClipPPOLoss
from torchrl.objectives.value import GAE

from echogym._progress import progress_bar
from echogym.client import connect
from echogym.train.checkpoint import load_checkpoint
from echogym.train.config import TrainConfig
from echogym.train.envs import default_obs_keys, env_factory
from echogym.train.eval_video import record_episode
from echogym.train.evaluation import evaluate
from echogym.train.models import GaussianSampler, norms
from echogym.train.networks import build_networks

#: Builds the collector: (policy, frames_per_batch, total_frames) → an iterable collector.
CollectorBuilder = Callable[[nn.Module, int, int], Any]


def resolve_device(name: str) -> torch.device:
    """``auto`` → CUDA when present, else CPU."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


#: Columns of ``progress.csv`` (a value missing from an iteration is left empty).
PROGRESS_FIELDS = [
    "iteration", "frames", "wall_time", "collect_fps", "fps", "collect_s", "update_s",
    "episodes", "episode_return", "episode_length", "success_rate", "reward_mean",
    "loss_objective", "loss_critic", "loss_entropy", "entropy", "clip_fraction", "kl_approx",
    "grad_norm", "lr", "value_mean", "advantage_std",
]


class _Logger:
    """``progress.csv`` + ``eval.csv`` + TensorBoard events in one directory (appending on resume)."""

    def __init__(self, logdir: Path) -> None:
        from torch.utils.tensorboard import SummaryWriter

        self.logdir = logdir
        self.writer = SummaryWriter(str(logdir / "tb"))
        self._files: dict[str, Any] = {}
        self._writers: dict[str, csv.DictWriter] = {}

    def row(self, name: str, step: int, values: dict[str, float]) -> None:
        path = self.logdir / f"{name}.csv"
        if name not in self._writers:
            exists = path.exists() and path.stat().st_size > 0
            fields = PROGRESS_FIELDS if name == "progress" else list(values)
            if exists:
                with open(path) as fh:
                    fields = next(csv.reader(fh))
            self._files[name] = open(path, "a", newline="")  # noqa: SIM115 (closed in close())
            self._writers[name] = csv.DictWriter(
                self._files[name], fieldnames=fields, extrasaction="ignore", restval=""
            )
            if not exists:
                self._writers[name].writeheader()
        self._writers[name].writerow(values)
        self._files[name].flush()
        for key, value in values.items():
            if isinstance(value, (int, float)) and key not in ("frames", "iteration"):
                if math.isfinite(float(value)):
                    self.writer.add_scalar(f"{name}/{key}", value, step)
        self.writer.flush()

    def close(self) -> None:
        for fh in self._files.values():
            fh.close()
        self.writer.close()


class PPOTrainer:
    """A PPO run: build with a config (and optionally a checkpoint to resume), then :meth:`train`.

    Args:
        cfg: The run's settings.
        resume: A checkpoint file or logdir to continue from (weights, normaliser,
            optimiser, frame counter, RNG).
        collector_builder: Builds the collector from (policy, frames_per_batch,
            total_frames); default a ``MultiSyncCollector`` of ``cfg.num_workers`` worker
            processes (a single in-process ``Collector`` when ``num_workers`` is 0).
    """

    def __init__(
        self,
        cfg: TrainConfig,
        resume: str | os.PathLike[str] | None = None,
        collector_builder: CollectorBuilder | None = None,
    ) -> None:
        self.cfg = cfg
        torch.set_num_threads(max(1, cfg.threads))
        self.device = resolve_device(cfg.device)
        self.logdir = Path(cfg.logdir)
        self.obs_keys = cfg.obs_keys or default_obs_keys(cfg.env_id, cfg.env_config)
        actor, critic = build_networks(cfg)
        self.actor = actor.to(self.device)
        self.critic = critic.to(self.device)
        self.loss = ClipPPOLoss(
            self.actor,
            self.critic,
            clip_epsilon=cfg.clip_epsilon,
            entropy_bonus=cfg.entropy_coef > 0,
            entropy_coeff=cfg.entropy_coef,
            critic_coeff=cfg.critic_coef,
            loss_critic_type="smooth_l1",
            normalize_advantage=True,
        )
        self.gae = GAE(
            gamma=cfg.gamma, lmbda=cfg.lmbda, value_network=self.critic, average_gae=False
        )
        self.optim = torch.optim.Adam(self.loss.parameters(), lr=cfg.lr, eps=1e-5)
        self.frames = 0
        self.iteration = 0
        self.wall_offset = 0.0
        self.norm_seeded = not cfg.normalize_observations
        if resume is not None:
            ckpt = load_checkpoint(resume)
            self.actor.load_state_dict(ckpt["actor"])
            self.critic.load_state_dict(ckpt["critic"])
            self.optim.load_state_dict(ckpt["optim"])
            self.frames = int(ckpt["frames"])
            self.iteration = int(ckpt["iteration"])
            self.wall_offset = float(ckpt.get("wall_time", 0.0))
            self.norm_seeded = bool(ckpt.get("norm_seeded", True))
            torch.set_rng_state(ckpt["rng"])
        self.collector_builder = collector_builder or self._default_collector

    def _default_collector(self, policy: nn.Module, frames_per_batch: int, total: int) -> Any:
        cfg = self.cfg
        if cfg.ray_servers:
            from echogym.train.scale_out import ray_collector

            return ray_collector(
                policy,
                env_id=cfg.env_id,
                env_config=cfg.env_config,
                obs_keys=self.obs_keys,
                servers=cfg.ray_servers,
                envs_per_worker=cfg.envs_per_worker,
                workers_per_server=max(1, cfg.num_workers),
                frames_per_batch=frames_per_batch,
                total_frames=total,
                address=cfg.ray_address,
                cpus_per_collector=cfg.ray_cpus_per_collector,
            )
        make_env = env_factory(
            cfg.env_id, cfg.envs_per_worker, cfg.env_config, self.obs_keys, cfg.server
        )
        if cfg.num_workers == 0:
            return Collector(make_env, policy, frames_per_batch=frames_per_batch,
                             total_frames=total, device="cpu")
        return MultiSyncCollector(
            [make_env] * cfg.num_workers,
            policy,
            frames_per_batch=frames_per_batch,
            total_frames=total,
            device="cpu",
        )

    # -- checkpoints -------------------------------------------------------------

    def state(self, wall: float) -> dict[str, Any]:
        """Everything a resume needs."""
        return {
            "config": asdict(self.cfg),
            "actor": {k: v.cpu() for k, v in self.actor.state_dict().items()},
            "critic": {k: v.cpu() for k, v in self.critic.state_dict().items()},
            "optim": self.optim.state_dict(),
            "frames": self.frames,
            "iteration": self.iteration,
            "wall_time": wall,
            "norm_seeded": self.norm_seeded,
            "rng": torch.get_rng_state(),
        }

    def save(self, wall: float) -> Path:
        """Write ``checkpoints/frames_<N>.pt`` and ``latest.pt`` (atomically replaced)."""
        folder = self.logdir / "checkpoints"
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"frames_{self.frames:010d}.pt"
        state = self.state(wall)
        torch.save(state, path)
        tmp = self.logdir / "latest.pt.tmp"
        torch.save(state, tmp)
        os.replace(tmp, self.logdir / "latest.pt")
        return path

    # -- one update --------------------------------------------------------------

    def _lr(self) -> float:
        if self.cfg.lr_schedule == "linear":
            return self.cfg.lr * max(0.0, 1.0 - self.frames / self.cfg.total_frames)
        return self.cfg.lr

    def _episode_stats(self, data: TensorDictBase) -> dict[str, float]:
        nxt = data["next"]
        done = nxt["done"].squeeze(-1)
        stats: dict[str, float] = {"episodes": float(done.sum())}
        if done.any():
            stats["episode_return"] = float(nxt["episode_reward"][done].mean())
            stats["episode_length"] = float(nxt["step_count"][done].float().mean())
            if "is_success" in nxt.keys():
                stats["success_rate"] = float((nxt["is_success"][done] > 0.5).float().mean())
        stats["reward_mean"] = float(nxt["reward"].mean())
        return stats

    def update(self, data: TensorDictBase) -> dict[str, float]:
        """PPO epochs on one batch ``[..., T]``; the mean losses."""
        cfg = self.cfg
        data = data.to(self.device)
        if cfg.success_bonus and "is_success" in data["next"].keys():
            won = (data["next", "is_success"] > 0.5).unsqueeze(-1) & data["next", "terminated"]
            data["next", "reward"] = data["next", "reward"] + cfg.success_bonus * won.float()
        with torch.no_grad():
            self.gae(data)
        flat = data.reshape(-1)
        n = flat.shape[0]
        mb = min(cfg.minibatch_size, n)
        for group in self.optim.param_groups:
            group["lr"] = self._lr()
        sums: dict[str, float] = {}
        steps = 0
        for _ in range(cfg.epochs):
            perm = torch.randperm(n, device=self.device)
            for start in range(0, n - mb + 1, mb):
                batch = flat[perm[start : start + mb]]
                losses = self.loss(batch)
                total = losses["loss_objective"] + losses["loss_critic"]
                if "loss_entropy" in losses.keys():
                    total = total + losses["loss_entropy"]
                self.optim.zero_grad(set_to_none=True)
                total.backward()
                grad_norm = nn.utils.clip_grad_norm_(self.loss.parameters(), cfg.max_grad_norm)
                self.optim.step()
                for key in ("loss_objective", "loss_critic", "loss_entropy", "entropy",
                            "clip_fraction", "kl_approx"):
                    if key in losses.keys():
                        sums[key] = sums.get(key, 0.0) + float(losses[key].detach().mean())
                sums["grad_norm"] = sums.get("grad_norm", 0.0) + float(grad_norm)
                steps += 1
        out = {k: v / max(steps, 1) for k, v in sums.items()}
        out["lr"] = self._lr()
        out["value_mean"] = float(flat["state_value"].mean())
        out["advantage_std"] = float(flat["advantage"].std())
        return out

    def _fold_norm(self, data: TensorDictBase) -> None:
        if not self.cfg.normalize_observations:
            return
        obs = data["observation"].to(self.device)
        for norm in norms(self.actor) + norms(self.critic):
            norm.update(obs)

    # -- the run -----------------------------------------------------------------

    def train(self) -> dict[str, Any]:
        """Collect and update until ``total_frames``; evaluate; the final summary."""
        cfg = self.cfg
        self.logdir.mkdir(parents=True, exist_ok=True)
        (self.logdir / "config.json").write_text(cfg.to_json())
        logger = _Logger(self.logdir)
        remaining = cfg.total_frames - self.frames
        if remaining <= 0:
            raise ValueError(
                f"the run already has {self.frames} frames; raise --total-frames to continue"
            )
        # Workers find this server (started privately for this process if none runs):
        # one server for every worker, living as long as the run.
        # With Ray, the servers run on their nodes (started by the operator).
        self._client = None if cfg.ray_servers else connect(cfg.server, autostart=True)
        # The actor's fused collection path; it holds the actor's modules under the same
        # names, so the weight sync below loads the actor's weights into it.
        policy = GaussianSampler(copy.deepcopy(self.actor).to("cpu"))
        collector = self.collector_builder(policy, cfg.frames_per_batch, remaining)
        collector.set_seed(cfg.seed + self.iteration * 7919)
        collector.update_policy_weights_(TensorDict.from_module(self.actor).data.cpu())
        bar = progress_bar(cfg.total_frames, enabled=cfg.progress, initial=self.frames,
                           unit="step", smoothing=0.1)
        start = time.monotonic()
        next_ckpt = (self.frames // cfg.checkpoint_every + 1) * cfg.checkpoint_every
        next_eval = (self.frames // cfg.eval_every + 1) * cfg.eval_every if cfg.eval_every else None
        collect_time = 0.0
        collected = 0
        last = None
        try:
            t_wait = time.monotonic()
            for data in collector:
                t_batch = time.monotonic() - t_wait
                batch_frames = data.numel()
                self.frames += batch_frames
                self.iteration += 1
                collect_time += t_batch
                collected += batch_frames
                row: dict[str, float] = {"iteration": self.iteration, "frames": self.frames}
                row.update(self._episode_stats(data))
                t_update = time.monotonic()
                if self.norm_seeded:
                    row.update(self.update(data))
                self._fold_norm(data)
                self.norm_seeded = True
                collector.update_policy_weights_(TensorDict.from_module(self.actor).data.cpu())
                wall = self.wall_offset + time.monotonic() - start
                row["update_s"] = time.monotonic() - t_update
                row["collect_s"] = t_batch
                row["collect_fps"] = batch_frames / max(t_batch, 1e-9)
                row["fps"] = collected / max(time.monotonic() - start, 1e-9)
                row["wall_time"] = wall
                logger.row("progress", self.frames, row)
                last = row
                bar.update(batch_frames)
                postfix = {"steps/s": f"{row['collect_fps']:.0f}"}
                if "episode_return" in row:
                    postfix["return"] = f"{row['episode_return']:.1f}"
                if "success_rate" in row:
                    postfix["success"] = f"{row['success_rate']:.2f}"
                bar.set_postfix(postfix)
                if self.frames >= next_ckpt:
                    self.save(wall)
                    next_ckpt += cfg.checkpoint_every
                if next_eval is not None and self.frames >= next_eval and self.frames < cfg.total_frames:
                    self._log_eval(logger, wall)
                    next_eval += cfg.eval_every
                t_wait = time.monotonic()
        finally:
            bar.close()
            collector.shutdown()
        wall = self.wall_offset + time.monotonic() - start
        ckpt = self.save(wall)
        evaluation = self._log_eval(logger, wall) if cfg.eval_episodes > 0 else None
        logger.close()
        summary = {
            "frames": self.frames,
            "iterations": self.iteration,
            "wall_time_s": wall,
            "collect_fps": collected / max(collect_time, 1e-9),
            "fps": collected / max(time.monotonic() - start, 1e-9),
            "checkpoint": str(ckpt),
            "last": last,
            "evaluation": None
            if evaluation is None
            else {k: v for k, v in evaluation.items() if k != "per_episode"},
        }
        (self.logdir / "summary.json").write_text(json.dumps(summary, indent=2))
        return summary

    def _log_eval(self, logger: _Logger, wall: float) -> dict[str, Any]:
        result = evaluate(copy.deepcopy(self.actor), self.cfg)
        if self.cfg.eval_video > 0:
            video = self.logdir / "videos" / f"eval-{self.frames:09d}.mp4"
            result["video"] = str(record_episode(copy.deepcopy(self.actor), self.cfg, video))
        row = {"frames": self.frames, "wall_time": wall}
        row.update({k: v for k, v in result.items() if k != "per_episode"})
        logger.row("eval", self.frames, row)
        return result
