"""`EchoEnv` for torchrl: a batch of server-side envs as one `EnvBase` with batch size ``[N]``.

Construction is cheap and does not touch the server: the spec is resolved locally from
the same registry the server uses, and the lease is taken on first use. torchrl's
collectors spawn worker processes that each build the env, and the parent often builds
a throw-away one; only envs that are actually stepped attach.

By default observations are copied out of shared memory into fresh tensors (torchrl's
``rollout`` and its collectors keep references to earlier steps). With
``copy_observations=False`` they are zero-copy ``torch.from_numpy`` views onto the
server's sample, valid until the next step/reset of the env: for code that consumes each
step before the next one. torchrl 0.14's collectors do not: they keep every step's
tensordict and stack the batch at its end, so under a collector a view shows the last
step's values (:func:`echogym.train.envs.build_env` concatenates the observation into a
fresh tensor, which is safe and is what training uses).
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

#: Sample slots whose tensors are kept (the native view cache keeps as many).
_SLOT_CACHE = 16

_TORCH_DTYPES = {"float32": torch.float32, "uint8": torch.uint8, "int32": torch.int32}
_CPU = torch.device("cpu")


class _Slot:
    """Tensors over one sample slot's views, built the first time the slot comes round.

    ``fields`` are the observation fields in spec order, ``reward``, ``terminated`` and
    ``truncated`` are ``[num_envs, 1]`` and ``info`` is ``[num_envs, info_size]``; all
    read-only views of the sample. ``extra`` is for subclasses' per-slot data.
    """

    __slots__ = ("views", "fields", "reward", "terminated", "truncated", "info", "extra")

    def __init__(self, views: tuple[Any, ...], num_envs: int) -> None:
        fields, reward, terminated, truncated, info, _, _ = views
        # Keep the tuple itself so its identity cannot be reused by another object.
        self.views = views
        self.fields = [_tensor(array) for array in fields]
        self.reward = _tensor(reward).view(num_envs, 1)
        self.terminated = _tensor(terminated).view(num_envs, 1)
        self.truncated = _tensor(truncated).view(num_envs, 1)
        self.info = _tensor(info)
        self.extra: Any = None


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
        # Info columns as a row index of the transposed info block: one `index_select`
        # gives every requested key as a contiguous row.
        self._info_rows = torch.tensor(self._info_index, dtype=torch.long)
        self._obs_names = [field["name"] for field in self.echo_spec["observation"]]
        self._slots: list[_Slot] = []
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

    def _slot(self, views: tuple[Any, ...]) -> _Slot:
        """The tensors over one sample slot's views, built once per slot.

        The native lease returns the same view tuple for a slot every time it comes round
        (the publisher cycles a few fixed slots), so the tensors over it are reused: a
        step wraps no array and validates nothing.
        """
        for slot in self._slots:
            if slot.views is views:
                return slot
        slot = _Slot(views, self.num_envs)
        if len(self._slots) >= _SLOT_CACHE:
            self._slots.pop(0)
        self._slots.append(slot)
        return slot

    def _small_entries(self, slot: _Slot, out: dict[str, Any], reward: bool = True) -> None:
        """Fresh copies of the info keys, the reward and the done flags into ``out``.

        Fresh because collectors write the root tensordict's flags in place and keep every
        step's entries, and the sample's memory is read-only and reused.
        """
        if self.info_keys:
            rows = slot.info.t().index_select(0, self._info_rows).unbind(0)
            for key, row in zip(self.info_keys, rows):
                out[key] = row
        if reward:
            out["reward"] = slot.reward.clone()
        terminated = slot.terminated.clone()
        truncated = slot.truncated.clone()
        out["terminated"] = terminated
        out["truncated"] = truncated
        out["done"] = terminated | truncated

    def _finish(self, out: dict[str, Any]) -> TensorDictBase:
        """A tensordict over ``out`` (every entry ``[num_envs, ...]`` on CPU by
        construction, so not validated again), moved to the env's device."""
        td = TensorDict._new_unsafe(out, batch_size=self.batch_size, device=_CPU)
        if self.device.type != "cpu":
            return td.to(self.device)
        return td

    def _deliver(self, views: tuple[Any, ...], reward: bool = True) -> TensorDictBase:
        slot = self._slot(views)
        copy = self.copy_observations
        out: dict[str, Any] = {}
        for name, tensor in zip(self._obs_names, slot.fields):
            out[name] = tensor.clone() if copy else tensor
        self._small_entries(slot, out, reward)
        return self._finish(out)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        mask = None
        if tensordict is not None and "_reset" in tensordict.keys():
            mask = tensordict.get("_reset").reshape(self.num_envs).cpu().numpy().astype(bool)
        seeds, self._seeds = self._seeds, None
        # A reset's flags are zero in the sample, so `done` comes out false; a reset
        # carries no reward.
        return self._deliver(self.lease.reset(mask, seeds), reward=False)

    @staticmethod
    def _action_array(tensordict: TensorDictBase) -> np.ndarray:
        """The tensordict's action as the contiguous float32 CPU array a step sends."""
        action = tensordict.get("action").detach()
        if action.device.type != "cpu" or action.dtype != torch.float32:
            action = action.to("cpu", torch.float32)
        if not action.is_contiguous():
            action = action.contiguous()
        return action.numpy()

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        return self._deliver(self.lease.step(self._action_array(tensordict)))

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
