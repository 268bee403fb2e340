"""Scale-out across machines with Ray: one ``echogym serve`` per node (shared memory is
host-local), and torchrl's :class:`~torchrl.collectors.distributed.RayCollector` placing
each node's collector next to its server.

Placement is by a Ray custom resource per server: a node whose server is named ``NAME``
joins the cluster with ``--resources '{"echogym_server_NAME": 1}'`` (see
:func:`server_resource`), and the collector that steps ``NAME``'s envs asks for that
resource, so Ray can only schedule it on that node. Each collector attaches to its node's
server by name; its env factory (``functools.partial``) travels pickled, the envs are built
where the collector runs. On one machine the same layout runs with several servers
under different names standing in for nodes (a local Ray cluster declares every
server's resource): that is how the tests and the 1-vs-2-node benchmark run here.

Multi-node set-up (docs/training.md has the full recipe)::

    # on every node (head first), NAME unique per node
    echogym serve --name NAME &
    ray start [--head | --address HEAD:6379] --resources '{"echogym_server_NAME": 1}'
    # anywhere in the cluster
    python -m echogym.train --ray-servers NAME1 NAME2 --ray-address auto ...
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import warnings
from collections.abc import Sequence
from typing import Any

import torch
from torch import nn

from echogym.train.config import TrainConfig
from echogym.train.envs import default_obs_keys, env_factory
from echogym.train.models import GaussianSampler
from echogym.train.networks import build_networks
from echogym.train.timing import timed_collection

#: Environment variables forwarded to Ray workers of a local cluster (the iceoryx2
#: location must match the servers').
FORWARDED_ENV = ("ECHOGYM_IPC_PREFIX", "ECHOGYM_IPC_ROOT", "ECHOGYM_SPIN_US", "ECHOGYM_LOG")


def server_resource(name: str) -> str:
    """The Ray custom resource that marks the node running server ``name``."""
    return "echogym_server_" + "".join(c if c.isalnum() or c in "_-" else "_" for c in name)


def ray_init_config(
    servers: Sequence[str], address: str | None = None, num_cpus: int | None = None
) -> dict[str, Any]:
    """``ray.init`` kwargs: join ``address`` (a cluster whose nodes declare their servers'
    resources), or start a local cluster declaring every server's resource."""
    env_vars = {k: os.environ[k] for k in FORWARDED_ENV if k in os.environ}
    runtime_env: dict[str, Any] = {"env_vars": env_vars} if env_vars else {}
    if address:
        config: dict[str, Any] = {"address": address}
    else:
        config = {
            "num_cpus": num_cpus or os.cpu_count() or 1,
            "resources": {server_resource(s): 1 for s in servers},
            "include_dashboard": False,
            "log_to_driver": False,
        }
    if runtime_env:
        config["runtime_env"] = runtime_env
    return config


def _closing_ray_collector() -> type:
    """``RayCollector`` whose remote collectors close their envs (give their leases back)
    before Ray kills them: torchrl's own ``shutdown`` kills the actors outright, so the
    server would only reclaim the leases once it notices the dead clients."""
    import ray
    from torchrl.collectors.distributed import RayCollector

    class ClosingRayCollector(RayCollector):
        def stop_remote_collectors(self) -> None:
            pending = [c.shutdown.remote() for c in self.remote_collectors]
            try:
                ray.get(pending, timeout=60)
            except Exception as exc:  # noqa: BLE001 (a dead actor: the server reclaims its lease)
                warnings.warn(f"a remote collector did not shut down cleanly: {exc}", stacklevel=2)
            super().stop_remote_collectors()

    return ClosingRayCollector


def ray_collector(
    policy: nn.Module,
    *,
    env_id: str,
    env_config: dict[str, Any],
    obs_keys: Sequence[str],
    servers: Sequence[str],
    envs_per_worker: int,
    workers_per_server: int = 1,
    frames_per_batch: int,
    total_frames: int,
    address: str | None = None,
    cpus_per_collector: float = 1.0,
    num_cpus: int | None = None,
) -> Any:
    """A synchronous ``RayCollector``: one remote collector per server, pinned to its node.

    With ``workers_per_server`` 1 the remote collector (a Ray actor) steps one lease of
    ``envs_per_worker`` envs itself; above 1 it is a ``MultiSyncCollector`` whose worker
    processes each take a lease. ``frames_per_batch`` is the total over all servers.
    """
    from torchrl.collectors import Collector, MultiSyncCollector

    factories = [
        env_factory(env_id, envs_per_worker, env_config, obs_keys, server) for server in servers
    ]
    remote_configs = [
        {"num_cpus": cpus_per_collector, "num_gpus": 0, "resources": {server_resource(s): 1}}
        for s in servers
    ]
    return _closing_ray_collector()(
        factories,
        policy,
        collector_class=Collector if workers_per_server == 1 else MultiSyncCollector,
        num_workers_per_collector=workers_per_server,
        frames_per_batch=frames_per_batch,
        total_frames=total_frames,
        sync=True,
        ray_init_config=ray_init_config(servers, address, num_cpus),
        remote_configs=remote_configs,
        collector_kwargs=[{} for _ in servers],
        device="cpu",
        storing_device="cpu",
    )


def measure(
    servers: Sequence[str],
    *,
    env_id: str,
    env_config: dict[str, Any],
    envs_per_worker: int,
    workers_per_server: int,
    frames_per_batch: int,
    batches: int,
    warmup: int = 2,
    address: str | None = None,
    cpus_per_collector: float = 1.0,
) -> dict[str, Any]:
    """Collection throughput (env-steps/s) of a ``RayCollector`` over ``servers`` with
    the default PPO actor (inference included, no training)."""
    cfg = TrainConfig(env_id=env_id, env_config=env_config)
    actor, _ = build_networks(cfg)
    collector = ray_collector(
        GaussianSampler(actor),
        env_id=env_id,
        env_config=env_config,
        obs_keys=default_obs_keys(env_id, env_config),
        servers=servers,
        envs_per_worker=envs_per_worker,
        workers_per_server=workers_per_server,
        frames_per_batch=frames_per_batch,
        total_frames=frames_per_batch * (batches + warmup),
        address=address,
        cpus_per_collector=cpus_per_collector,
    )
    frames, elapsed = timed_collection(collector, warmup)
    return {"servers": list(servers), "frames": frames, "seconds": elapsed,
            "env_steps_per_s": frames / elapsed}


def main(argv: list[str] | None = None) -> int:
    """``python -m echogym.train.scale_out``: measure Ray collection over 1..N servers."""
    parser = argparse.ArgumentParser(
        prog="python -m echogym.train.scale_out",
        description="Collection throughput of a RayCollector over the first 1..N of the given "
        "servers (each a running `echogym serve --name NAME`).",
    )
    parser.add_argument("--servers", nargs="+", required=True)
    parser.add_argument("--env-id", default="echogym/PushCube-v0")
    parser.add_argument("--env-config", type=json.loads, default={})
    parser.add_argument("--envs-per-worker", type=int, default=16)
    parser.add_argument("--workers-per-server", type=int, default=1)
    parser.add_argument("--frames-per-batch", type=int, default=4096)
    parser.add_argument("--batches", type=int, default=10, help="measured batches")
    parser.add_argument("--warmup", type=int, default=2, help="batches before the clock starts")
    parser.add_argument("--address", default=None, help="Ray cluster address (default: local)")
    parser.add_argument("--cpus-per-collector", type=float, default=1.0)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    import ray

    results = []
    for n in range(1, len(args.servers) + 1):
        result = measure(
            args.servers[:n],
            env_id=args.env_id,
            env_config=args.env_config,
            envs_per_worker=args.envs_per_worker,
            workers_per_server=args.workers_per_server,
            frames_per_batch=args.frames_per_batch,
            batches=args.batches,
            warmup=args.warmup,
            address=args.address,
            cpus_per_collector=args.cpus_per_collector,
        )
        results.append(result)
        print(json.dumps(result), flush=True)
        ray.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
