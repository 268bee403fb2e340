"""PPO on echogym with torchrl 0.14: ``ClipPPOLoss``, ``GAE``, and a
``MultiSyncCollector`` whose worker processes each attach to the server and step a batch
of server-side envs (or any collector a caller builds, e.g. Ray's, see
:mod:`echogym.train.scale_out`).

One iteration: the collector returns ``num_workers × envs_per_worker × T`` transitions
(time last, as GAE wants) → advantages → ``epochs`` passes of shuffled minibatches →
the observation normaliser folds in the batch → the new weights (normaliser included)
go to the workers. The first batch of a fresh run only seeds the normaliser: its actions
were drawn by a policy that saw unnormalised observations.

Logs (``LOGDIR``): ``progress.csv`` and TensorBoard events per iteration, ``eval.csv`` per
evaluation, ``checkpoints/frames_*.pt`` and ``latest.pt`` (weights, normaliser, optimiser,
counters, RNG, config), ``config.json``, ``summary.json`` at the end.
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

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.collectors import Collector, MultiSyncCollector
from torchrl.data import Bounded
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.objectives import ClipPPOLoss
from torchrl.objectives.value import GAE

from echogym._native import resolve_spec
from echogym.client import connect
from echogym.train.config import TrainConfig
from echogym.train.envs import build_env, default_obs_keys, env_factory, obs_size
from echogym.train.models import make_actor, make_critic, norms

#: Builds the collector: (policy, frames_per_batch, total_frames) → an iterable collector.
CollectorBuilder = Callable[[nn.Module, int, int], Any]


def resolve_device(name: str) -> torch.device:
    """``auto`` → CUDA when present, else CPU."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


def _action_spec(cfg: TrainConfig) -> Bounded:
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
    actor = make_actor(size, _action_spec(cfg), cfg.hidden, cfg.activation, cfg.log_std_init)
    critic = make_critic(size, cfg.hidden, cfg.activation)
    return actor, critic


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
    return _ZeroPolicy(_action_spec(cfg).shape[-1])


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
        from tqdm import tqdm

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
        policy = copy.deepcopy(self.actor).to("cpu")
        collector = self.collector_builder(policy, cfg.frames_per_batch, remaining)
        collector.set_seed(cfg.seed + self.iteration * 7919)
        collector.update_policy_weights_(TensorDict.from_module(self.actor).data.cpu())
        bar = tqdm(total=cfg.total_frames, initial=self.frames, unit="step",
                   disable=not cfg.progress, dynamic_ncols=True, smoothing=0.1)
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
        row = {"frames": self.frames, "wall_time": wall}
        row.update({k: v for k, v in result.items() if k != "per_episode"})
        logger.row("eval", self.frames, row)
        return result
