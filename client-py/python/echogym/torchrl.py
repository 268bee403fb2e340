"""`EchoEnv` for torchrl: a batch of server-side envs as one `EnvBase` with batch size ``[N]``.

Construction is cheap and does not touch the server: the spec is resolved locally from
the same registry the server uses, and the lease is taken on first use. torchrl's
collectors spawn worker processes that each build the env, and the parent often builds
a throw-away one; only envs that are actually stepped attach.

By default observations are copied out of shared memory into fresh tensors (torchrl's
``rollout`` keeps references to earlier steps). With ``copy_observations=False`` they
are zero-copy ``torch.from_numpy`` views onto the server's sample, valid until the next
step/reset of the env: safe with collectors, which copy every step into their own
buffers, and the fastest path.
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from echogym._native import NativeLease, resolve_spec
from echogym.client import connect

#: Sample slots whose tensordicts are kept (the native view cache keeps as many).
_SLOT_CACHE = 16

_TORCH_DTYPES = {"float32": torch.float32, "uint8": torch.uint8, "int32": torch.int32}


def _tensor(array: np.ndarray) -> torch.Tensor:
    # The views are read-only by design; torch warns once about that and we never write.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return torch.from_numpy(array)


class EchoEnv(EnvBase):
    """``num_envs`` echogym envs as one torchrl env (partial resets via ``"_reset"``).

    Args:
        env_id: Versioned echogym id, e.g. ``"echogym/Null-v0"``.
        num_envs: Envs in the batch (the env's ``batch_size`` is ``[num_envs]``).
        server: Server name (default ``$ECHOGYM_SERVER`` or ``"default"``).
        autostart: Start a private server if none is running (default true).
        device: Where tensors are returned (default CPU).
        copy_observations: Copy observations out of shared memory (default true); see
            the module docs for the zero-copy mode.
        info_keys: Info values to return next to the observations, each a float32
            entry of shape ``[num_envs]`` named by its key (``"is_success"``,
            ``"contact_force"``, ...); ``True`` returns every key the env declares.
            Default none (what ``check_env_specs`` and collectors need is unchanged).
        **config: Env config; unknown keys raise :class:`echogym.InvalidConfigError`.
    """

    def __init__(
        self,
        env_id: str,
        num_envs: int = 1,
        *,
        server: str | None = None,
        autostart: bool = True,
        device: Any = "cpu",
        copy_observations: bool = True,
        info_keys: Sequence[str] | bool = (),
        **config: Any,
    ) -> None:
        super().__init__(device=device, batch_size=torch.Size([num_envs]))
        self.copy_observations = copy_observations
        self.env_id = env_id
        self.num_envs = num_envs
        self.server = server
        self.autostart = autostart
        self.config = config
        self.echo_spec: dict[str, Any] = json.loads(resolve_spec(env_id, json.dumps(config)))
        declared: list[str] = self.echo_spec["info_keys"]
        keys = declared if info_keys is True else list(info_keys or ())
        unknown = [k for k in keys if k not in declared]
        if unknown:
            raise ValueError(f"{env_id} has no info keys {unknown}; it declares {declared}")
        self.info_keys = keys
        self._info_index = [declared.index(k) for k in keys]
        self._lease: NativeLease | None = None
        self._seeds: list[int | None] | None = None
        self._slots: list[tuple[tuple[Any, ...], TensorDictBase]] = []
        self._small_keys = [*self.info_keys, "reward", "terminated", "truncated", "done"]
        self._make_specs()

    def _make_specs(self) -> None:
        n = self.num_envs
        obs = {}
        for field in self.echo_spec["observation"]:
            shape = (n, *field["shape"])
            dtype = _TORCH_DTYPES[field["dtype"]]
            if field["low"] is not None and field["high"] is not None:
                obs[field["name"]] = Bounded(
                    low=field["low"], high=field["high"], shape=shape, dtype=dtype, device=self.device
                )
            else:
                obs[field["name"]] = Unbounded(shape=shape, dtype=dtype, device=self.device)
        for key in self.info_keys:
            obs[key] = Unbounded(shape=(n,), dtype=torch.float32, device=self.device)
        self.observation_spec = Composite(obs, shape=(n,), device=self.device)
        action = self.echo_spec["action"]
        self.action_spec = Bounded(
            low=torch.tensor(action["low"], dtype=torch.float32).expand(n, -1),
            high=torch.tensor(action["high"], dtype=torch.float32).expand(n, -1),
            shape=(n, action["size"]),
            dtype=torch.float32,
            device=self.device,
        )
        self.reward_spec = Unbounded(shape=(n, 1), dtype=torch.float32, device=self.device)
        flag = lambda: Categorical(2, shape=(n, 1), dtype=torch.bool, device=self.device)  # noqa: E731
        self.done_spec = Composite(
            done=flag(), terminated=flag(), truncated=flag(), shape=(n,), device=self.device
        )

    @property
    def lease(self) -> NativeLease:
        """The server lease, taken on first use."""
        if self._lease is None:
            client = connect(self.server, autostart=self.autostart)
            self._lease = client.attach(self.env_id, self.num_envs, self.config, "disabled")
            served = json.loads(self._lease.spec_json)
            if served["observation"] != self.echo_spec["observation"] or (
                served["action"] != self.echo_spec["action"]
            ):
                self._lease.close()
                raise RuntimeError(
                    f"the server's spec of {self.env_id} differs from this client's; "
                    "install matching echogym versions"
                )
        return self._lease

    def _views(self, views: tuple[Any, ...]) -> TensorDictBase:
        """The tensordict over one sample slot's views, built once per slot.

        The native lease returns the same view tuple for a slot every time it comes round
        (the publisher cycles a few fixed slots), so the tensors, the ``done`` buffer and
        the tensordict (validated once, at construction) are reused: a step allocates no
        tensor and validates nothing. ``done`` is a per-slot buffer written in place.
        """
        for cached_views, cached in self._slots:
            if cached_views is views:
                return cached
        fields, reward, terminated, truncated, info, _, _ = views
        n = self.num_envs
        out: dict[str, torch.Tensor] = {}
        for field, array in zip(self.echo_spec["observation"], fields):
            out[field["name"]] = _tensor(array)
        info_t = _tensor(info)
        for key, column in zip(self.info_keys, self._info_index):
            out[key] = info_t[:, column]
        term = _tensor(terminated).view(n, 1)
        trunc = _tensor(truncated).view(n, 1)
        out["reward"] = _tensor(reward).view(n, 1)
        out["terminated"] = term
        out["truncated"] = trunc
        out["done"] = torch.empty((n, 1), dtype=torch.bool)
        td = TensorDict(out, batch_size=self.batch_size, device="cpu")
        if len(self._slots) >= _SLOT_CACHE:
            self._slots.pop(0)
        # Keep the tuple itself so its identity cannot be reused by another object.
        self._slots.append((views, td))
        return td

    def _deliver(self, views: tuple[Any, ...]) -> TensorDictBase:
        td = self._views(views)
        done = td.get("done")
        torch.logical_or(td.get("terminated"), td.get("truncated"), out=done)
        if self.device.type != "cpu":
            return td.to(self.device)
        if self.copy_observations:
            return td.clone()
        # A new tensordict over the same observation views (torchrl's transforms add and
        # delete keys of what `_step` returns, which must not reach the cached one). The
        # reward, flags and info are fresh: collectors write into the root tensordict's
        # flags in place, and the sample's memory is read-only.
        out = td.copy()
        for key in self._small_keys:
            out.set(key, out.get(key).clone())
        return out

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        mask = None
        if tensordict is not None and "_reset" in tensordict.keys():
            mask = tensordict.get("_reset").reshape(self.num_envs).cpu().numpy().astype(bool)
        seeds, self._seeds = self._seeds, None
        # A reset's flags are zero in the sample, so `done` comes out false; a reset
        # carries no reward.
        return self._deliver(self.lease.reset(mask, seeds)).exclude("reward")

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get("action").detach()
        if action.device.type != "cpu" or action.dtype != torch.float32:
            action = action.to("cpu", torch.float32)
        if not action.is_contiguous():
            action = action.contiguous()
        return self._deliver(self.lease.step(action.numpy()))

    def _set_seed(self, seed: int | None) -> int | None:
        if seed is None:
            return None
        self._seeds = [seed + i for i in range(self.num_envs)]
        return seed + self.num_envs

    def close(self, *, raise_if_closed: bool = True) -> None:
        """Give the lease back to the server."""
        if self._lease is not None:
            self._lease.close()
            self._lease = None
        self._slots.clear()
        super().close(raise_if_closed=raise_if_closed)

    def __getstate__(self) -> dict[str, Any]:
        # Pickled for worker processes: the lease is per process and re-taken lazily.
        state = self.__dict__.copy()
        state["_lease"] = None
        state["_slots"] = []
        return state
