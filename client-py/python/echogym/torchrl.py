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

    def _obs(self, fields: tuple[np.ndarray, ...], out: dict[str, torch.Tensor]) -> None:
        for field, array in zip(self.echo_spec["observation"], fields):
            tensor = _tensor(array)
            if self.device.type != "cpu":
                tensor = tensor.to(self.device, non_blocking=False)
            elif self.copy_observations:
                tensor = tensor.clone()
            out[field["name"]] = tensor

    def _info(self, info: np.ndarray, out: dict[str, torch.Tensor]) -> None:
        for key, column in zip(self.info_keys, self._info_index):
            out[key] = torch.tensor(info[:, column], dtype=torch.float32, device=self.device)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        mask = None
        if tensordict is not None and "_reset" in tensordict.keys():
            mask = tensordict.get("_reset").reshape(self.num_envs).cpu().numpy().astype(bool)
        seeds, self._seeds = self._seeds, None
        fields, _, _, _, info, _, _ = self.lease.reset(mask, seeds)
        out: dict[str, torch.Tensor] = {}
        self._obs(fields, out)
        self._info(info, out)
        zeros = torch.zeros((self.num_envs, 1), dtype=torch.bool, device=self.device)
        out["done"] = zeros
        out["terminated"] = zeros.clone()
        out["truncated"] = zeros.clone()
        return TensorDict(out, batch_size=self.batch_size, device=self.device)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get("action").detach().to("cpu", torch.float32).numpy()
        fields, reward, terminated, truncated, info, _, _ = self.lease.step(
            np.ascontiguousarray(action)
        )
        out: dict[str, torch.Tensor] = {}
        self._obs(fields, out)
        self._info(info, out)
        term = _tensor(terminated).reshape(self.num_envs, 1).to(self.device, copy=True)
        trunc = _tensor(truncated).reshape(self.num_envs, 1).to(self.device, copy=True)
        out["reward"] = _tensor(reward).reshape(self.num_envs, 1).to(self.device, copy=True)
        out["terminated"] = term
        out["truncated"] = trunc
        out["done"] = term | trunc
        return TensorDict(out, batch_size=self.batch_size, device=self.device)

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
        super().close(raise_if_closed=raise_if_closed)

    def __getstate__(self) -> dict[str, Any]:
        # Pickled for worker processes: the lease is per process and re-taken lazily.
        state = self.__dict__.copy()
        state["_lease"] = None
        return state
