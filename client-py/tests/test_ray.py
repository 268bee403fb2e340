"""Scale-out with Ray: two `echogym serve` processes under different names stand in for
two nodes of a local Ray cluster; `python -m echogym.train --ray-servers A B` trains PPO
through torchrl's `RayCollector`, one remote collector pinned to each server by the
server's Ray resource. Both servers serve env steps, both collectors give their leases
back, and the run's losses are finite."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
import time

import pytest

pytest.importorskip("ray")

from conftest import Server  # noqa: E402


def test_ppo_through_ray_collectors_on_two_servers(ipc, tmp_path):
    servers = [Server("node-a", ipc), Server("node-b", ipc)]
    try:
        logdir = tmp_path / "ray"
        result = subprocess.run(
            [sys.executable, "-m", "echogym.train", "--env-id", "echogym/PushCube-v0",
             "--ray-servers", "node-a", "node-b", "--num-workers", "1",
             "--envs-per-worker", "4", "--frames-per-batch", "512", "--total-frames", "1536",
             "--epochs", "2", "--minibatch-size", "128", "--hidden", "32", "32",
             "--ray-cpus-per-collector", "0.5", "--eval-episodes", "0",
             "--checkpoint-every", "100000", "--progress", "false", "--logdir", str(logdir)],
            capture_output=True, text=True, timeout=600,
        )
        assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
        summary = json.loads((logdir / "summary.json").read_text())
        assert summary["frames"] == 1536
        with open(logdir / "progress.csv") as fh:
            rows = list(csv.DictReader(fh))
        assert len(rows) == 3
        for row in rows[1:]:
            assert math.isfinite(float(row["loss_objective"]))
            assert math.isfinite(float(row["loss_critic"]))
        for server in servers:
            deadline = time.monotonic() + 5
            while server.status()["leases"] and time.monotonic() < deadline:
                time.sleep(0.05)
            status = server.status()
            # Each server stepped its own collector's half of every batch.
            assert status["env_steps"] >= 1536 // 2, (server.name, status)
            assert status["leases"] == [], f"{server.name}: a collector kept its lease"
            assert status["reclaimed_leases"] == 0, f"{server.name}: a lease was reclaimed"
    finally:
        for server in servers:
            if server.process.poll() is None:
                assert server.stop() == 0
