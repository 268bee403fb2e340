"""`AsyncCollector`: torchrl transitions from envpool-style asynchronous batches.

torchrl's collectors step a batch-locked env synchronously; this collector drives an
:class:`echogym.gym_async.EchoAsyncVectorEnv` instead: ``recv`` the first ``batch_size``
envs ready, run the policy (any ``TensorDictModule`` reading ``"observation"`` and
writing ``"action"``, e.g. :class:`echogym.train.models.GaussianSampler`) on them,
``send`` the actions, and pair each env's previous observation and action with the
result that comes back for it. Batches are flat tensordicts of ``frames_per_batch``
transitions, torchrl's layout (``"observation"``, ``"action"``, the policy's other
outputs, ``("next", "observation" | "reward" | "done" | "terminated" | "truncated")``)
plus ``"env_id"``: transitions of one env are in order, those of different envs
interleaved (group them by ``env_id`` for advantage estimates over trajectories).
Same-step autoreset: an ended episode's last observation is its transition's
``("next", "observation")``; the env's next transition starts from its reset.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.envs.utils import ExplorationType, set_exploration_type

from echogym.gym_async import EchoAsyncVectorEnv


class AsyncCollector:
    """Transitions from ``num_envs`` envs stepped asynchronously, ``batch_size`` at a time.

    Args:
        env_id: Versioned echogym id.
        num_envs: All envs (N).
        batch_size: Envs per policy call (M ≤ N; ``recv`` returns the first M ready).
        policy: Reads ``"observation"`` ``[M, D]``, writes ``"action"`` ``[M, A]``.
        frames_per_batch: Transitions per yielded batch.
        total_frames: Transitions in all (the iteration ends after them).
        obs_keys: Observation fields concatenated into ``"observation"`` (default every
            1-D float field, as :func:`echogym.train.envs.default_obs_keys`).
        group_size: Envs per lease (default ``batch_size``); see ``EchoAsyncVectorEnv``.
        seed: Env ``i`` is reset with ``seed + i`` (default: unseeded).
        server: Server name (default ``$ECHOGYM_SERVER`` or ``"default"``).
        exploration: torchrl exploration type of the policy calls (default random).
        **config: Env config.
    """

    def __init__(
        self,
        env_id: str,
        num_envs: int,
        batch_size: int,
        policy: Any,
        frames_per_batch: int,
        total_frames: int,
        *,
        obs_keys: Sequence[str] | None = None,
        group_size: int | None = None,
        seed: int | None = None,
        server: str | None = None,
        exploration: ExplorationType = ExplorationType.RANDOM,
        **config: Any,
    ) -> None:
        self.env = EchoAsyncVectorEnv(env_id, num_envs, batch_size, group_size=group_size,
                                      server=server, autoreset_mode="same_step", **config)
        fields = self.env.echo_spec["observation"]
        if obs_keys is None:
            obs_keys = [f["name"] for f in fields
                        if f["dtype"] == "float32" and len(f["shape"]) == 1]
        names = [f["name"] for f in fields]
        unknown = [k for k in obs_keys if k not in names]
        if unknown:
            raise ValueError(f"{env_id} has no observation fields {unknown}; it has {names}")
        self.obs_keys = list(obs_keys)
        self.policy = policy
        self.frames_per_batch = frames_per_batch
        self.total_frames = total_frames
        self.exploration = exploration
        self.seed = seed
        self._prev: TensorDictBase | None = None  # per env: last observation and policy output

    def _observation(self, obs: Any) -> torch.Tensor:
        arrays = [obs] if isinstance(obs, np.ndarray) else [obs[k] for k in self.obs_keys]
        return torch.from_numpy(np.concatenate(arrays, axis=-1, dtype=np.float32))

    def _act(self, observation: torch.Tensor, ids: np.ndarray) -> None:
        """Run the policy on the envs ``ids``, remember its output, send the actions."""
        td = TensorDict({"observation": observation}, batch_size=[len(ids)])
        with torch.no_grad(), set_exploration_type(self.exploration):
            td = self.policy(td)
        if self._prev is None:
            self._prev = td.new_zeros(self.env.num_envs)
        self._prev[torch.from_numpy(ids)] = td
        self.env.send(td.get("action").numpy(), ids)

    def __iter__(self) -> Iterator[TensorDictBase]:
        self.env.async_reset(self.seed)
        # Envs whose last result answered an action (not the reset): those give transitions.
        acted = np.zeros(self.env.num_envs, dtype=bool)
        pending: list[TensorDictBase] = []
        frames = produced = 0
        while produced < self.total_frames:
            obs, reward, terminated, truncated, info = self.env.recv()
            ids = info["env_id"]
            current = self._observation(obs)
            rows = np.flatnonzero(acted[ids])
            if len(rows):
                pending.append(self._transitions(rows, ids, current, reward, terminated,
                                                 truncated, info))
                frames += len(rows)
            acted[ids] = True
            self._act(current, ids)
            while frames >= self.frames_per_batch and produced < self.total_frames:
                batch = torch.cat(pending)
                out, rest = batch[: self.frames_per_batch], batch[self.frames_per_batch:]
                pending = [rest] if rest.numel() else []
                frames = rest.numel()
                produced += out.numel()
                yield out

    def _transitions(self, rows: np.ndarray, ids: np.ndarray, current: torch.Tensor,
                     reward: np.ndarray, terminated: np.ndarray, truncated: np.ndarray,
                     info: dict[str, Any]) -> TensorDictBase:
        """The transitions that the result rows ``rows`` of envs ``ids`` complete."""
        assert self._prev is not None
        next_obs = current[torch.from_numpy(rows)].clone()
        if "final_obs" in info:
            for i, row in enumerate(rows):
                if info["_final_obs"][row]:
                    next_obs[i] = self._observation(_as_batch(info["final_obs"][row]))[0]
        env_ids = torch.from_numpy(ids[rows])
        n = len(rows)
        term = torch.from_numpy(terminated[rows]).reshape(n, 1)
        trunc = torch.from_numpy(truncated[rows]).reshape(n, 1)
        transition = self._prev[env_ids].clone()
        transition.set("env_id", env_ids)
        transition.set("next", TensorDict({
            "observation": next_obs,
            "reward": torch.from_numpy(reward[rows]).reshape(n, 1),
            "terminated": term,
            "truncated": trunc,
            "done": term | trunc,
        }, batch_size=[n]))
        return transition

    def shutdown(self) -> None:
        """Give the envs back."""
        self.env.close()


def _as_batch(obs: Any) -> Any:
    """One env's observation (array or dict of arrays) as a batch of one."""
    if isinstance(obs, dict):
        return {k: np.asarray(v)[None] for k, v in obs.items()}
    return np.asarray(obs)[None]
