"""Training (`python -m echogym.train`): a short PPO run on PushCube with two collector
worker processes completes with finite losses, writes checkpoints, logs (CSV, TensorBoard)
and an evaluation, resumes from its checkpoint where it stopped, and its workers attach to
the server and detach cleanly (every lease given back by its client, none reclaimed).
Also the pieces it rests on: the running observation normaliser and the torchrl env's
info keys."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
import time

import numpy as np
import pytest
import torch

pytest.importorskip("torchrl")

from echogym.torchrl import EchoEnv  # noqa: E402
from echogym.train.models import RunningNorm  # noqa: E402

SMALL = [
    "--env-id", "echogym/PushCube-v0", "--num-workers", "2", "--envs-per-worker", "4",
    "--frames-per-batch", "512", "--epochs", "2", "--minibatch-size", "128",
    "--hidden", "32", "32", "--eval-episodes", "4", "--eval-envs", "4", "--eval-video", "96",
    "--checkpoint-every", "1024", "--progress", "false", "--seed", "3",
]


def _train(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "echogym.train", *args],
        capture_output=True, text=True, timeout=600,
    )


def _rows(path) -> list[dict[str, str]]:
    with open(path) as fh:
        return list(csv.DictReader(fh))


def _wait_for_no_leases(server) -> dict:
    deadline = time.monotonic() + 5
    while server.status()["leases"] and time.monotonic() < deadline:
        time.sleep(0.05)
    return server.status()


def test_short_ppo_run_checkpoints_resumes_and_detaches(server, tmp_path):
    logdir = tmp_path / "run"
    first = _train(*SMALL, "--total-frames", "2048", "--logdir", str(logdir))
    assert first.returncode == 0, first.stdout[-3000:] + first.stderr[-3000:]
    summary = json.loads((logdir / "summary.json").read_text())
    assert summary["frames"] == 2048
    assert (logdir / "checkpoints" / "frames_0000001024.pt").exists()
    assert (logdir / "checkpoints" / "frames_0000002048.pt").exists()
    rows = _rows(logdir / "progress.csv")
    assert [int(r["frames"]) for r in rows] == [512, 1024, 1536, 2048]
    # The first batch only seeds the normaliser; every later one trains with finite losses.
    for row in rows[1:]:
        for key in ("loss_objective", "loss_critic", "grad_norm"):
            assert math.isfinite(float(row[key])), (key, row)
    assert any(p.name.startswith("events.out.tfevents") for p in (logdir / "tb").iterdir())
    evaluation = summary["evaluation"]
    assert evaluation["episodes"] == 4 and 0.0 <= evaluation["success_mean"] <= 1.0
    # The evaluation's video: one deterministic episode, 96 × 96, the arm moving.
    assert evaluation["video"] == str(logdir / "videos" / "eval-000002048.mp4")
    import imageio.v2 as imageio

    reader = imageio.get_reader(evaluation["video"], format="FFMPEG")
    frames = [f for f in reader]
    reader.close()
    assert frames[0].shape == (96, 96, 3) and len(frames) >= 10
    assert any((f != frames[0]).any() for f in frames[1:])

    status = _wait_for_no_leases(server)
    assert status["leases"] == [], "workers left leases behind"
    assert status["reclaimed_leases"] == 0, "a worker died without giving its lease back"
    steps_first = status["env_steps"]
    assert steps_first >= 2048

    ckpt = torch.load(logdir / "latest.pt", weights_only=False)
    assert ckpt["frames"] == 2048
    norm_count = float(ckpt["actor"]["module.0.module.norm.count"])
    assert norm_count > 2048  # every collected batch was folded into the normaliser

    resumed = _train("--resume", str(logdir), "--total-frames", "3072", "--progress", "false")
    assert resumed.returncode == 0, resumed.stdout[-3000:] + resumed.stderr[-3000:]
    rows = _rows(logdir / "progress.csv")
    assert [int(r["frames"]) for r in rows][-2:] == [2560, 3072]
    assert int(rows[-2]["iteration"]) == 5  # counters continue, nothing restarts
    assert math.isfinite(float(rows[-2]["loss_objective"]))  # no second normaliser warm-up
    ckpt2 = torch.load(logdir / "latest.pt", weights_only=False)
    assert ckpt2["frames"] == 3072
    assert ckpt2["wall_time"] > ckpt["wall_time"]
    moved = any(
        not torch.equal(ckpt["actor"][k], ckpt2["actor"][k]) for k in ckpt["actor"]
    )
    assert moved, "resuming trained nothing"
    status = _wait_for_no_leases(server)
    assert status["leases"] == [] and status["reclaimed_leases"] == 0
    assert status["env_steps"] >= steps_first + 1024

    evaluated = _train("--eval-only", str(logdir), "--eval-episodes", "2", "--eval-envs", "2")
    assert evaluated.returncode == 0, evaluated.stderr[-3000:]
    report = json.loads(evaluated.stdout[evaluated.stdout.index("{"):])
    assert report["episodes"] == 2 and len(report["per_episode"]) == 2


def test_running_norm_matches_the_moments_of_all_batches():
    rng = np.random.default_rng(0)
    norm = RunningNorm(3)
    batches = [rng.normal([1.0, -2.0, 5.0], [0.5, 3.0, 0.1], size=(n, 3)) for n in (7, 100, 33)]
    for batch in batches:
        norm.update(torch.tensor(batch, dtype=torch.float32))
    data = np.concatenate(batches)
    np.testing.assert_allclose(norm.mean.numpy(), data.mean(0), rtol=1e-4, atol=1e-4)
    # The prior (count 1e-4, mean 0, var 1, as SB3's RunningMeanStd) shifts the var by ~1e-5.
    np.testing.assert_allclose(norm.var.numpy(), data.var(0), rtol=1e-3, atol=1e-4)
    out = norm(torch.tensor(data, dtype=torch.float32)).numpy()
    np.testing.assert_allclose(out.mean(0), 0.0, atol=1e-3)
    np.testing.assert_allclose(out.std(0), 1.0, atol=3e-3)


def test_torchrl_env_returns_requested_info_keys(server):
    env = EchoEnv("echogym/PushCube-v0", num_envs=2, info_keys=["is_success", "cube_to_goal"])
    rollout = env.rollout(3)
    distance = rollout["next", "cube_to_goal"]
    assert distance.shape == (2, 3)
    # The goal is drawn 10-18 cm from the cube and three random steps barely move it.
    assert ((distance > 0.05) & (distance < 0.25)).all()
    assert (rollout["next", "is_success"] == 0).all()
    env.close()
    with pytest.raises(ValueError, match="no info keys"):
        EchoEnv("echogym/PushCube-v0", num_envs=1, info_keys=["nope"])


def test_gaussian_sampler_is_the_actors_distribution():
    # The collection path (GaussianSampler) against the PPO loss's ProbabilisticActor:
    # the same loc and scale bit for bit, the log-probability of its action under the
    # actor's distribution to float rounding, the mean when deterministic.
    from tensordict import TensorDict
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    from echogym.train.config import TrainConfig
    from echogym.train.models import GaussianSampler
    from echogym.train.networks import build_networks

    actor, _ = build_networks(TrainConfig(env_id="echogym/PushCube-v0"))
    net = actor.module[0].module
    with torch.no_grad():
        net.log_std.copy_(torch.linspace(-1.0, 0.5, net.log_std.numel()))
        net.norm.mean.normal_()
        net.norm.var.uniform_(0.5, 2.0)
    sampler = GaussianSampler(actor)
    obs = torch.randn(16, net.norm.mean.numel()) * 3
    with torch.no_grad():
        dist = actor.get_dist(TensorDict({"observation": obs}, [16]))
        ref = actor.module[0](TensorDict({"observation": obs}, [16]))
        for mode in (ExplorationType.RANDOM, ExplorationType.DETERMINISTIC):
            with set_exploration_type(mode):
                out = sampler(TensorDict({"observation": obs}, [16]))
            assert torch.equal(out["loc"], ref["loc"]) and torch.equal(out["scale"], ref["scale"])
            torch.testing.assert_close(out["action_log_prob"], dist.log_prob(out["action"]),
                                       rtol=0, atol=1e-5)
            if mode is ExplorationType.DETERMINISTIC:
                assert torch.equal(out["action"], out["loc"])
            else:
                assert not torch.equal(out["action"], out["loc"])
