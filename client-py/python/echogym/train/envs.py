"""The env a PPO worker steps: :class:`echogym.torchrl.EchoEnv` (a batch of server-side
envs) with the observation fields concatenated into one ``"observation"`` vector, the
episode return and length tracked, and the info keys the trainer reports on
(:class:`WorkerEnv`: what ``TransformedEnv(EchoEnv, Compose(CatTensors, RewardSum,
StepCounter))`` gives, computed in one pass per step).

Factories are ``functools.partial`` of module-level functions, so they pickle into
collector worker processes (spawned) and Ray actors; each worker builds its own env and
takes its own lease on first use.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable, Sequence
from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase, is_tensor_collection
from torchrl.data import Bounded, Composite, Unbounded
from torchrl.envs import EnvBase

from echogym._native import resolve_spec
from echogym.torchrl import EchoEnv, _Slot

#: Info keys reported (as episode-end values) when the env declares them.
REPORTED_INFO = ("is_success", "contact_force", "in_contact", "progress", "cube_to_goal")


def default_obs_keys(env_id: str, env_config: dict[str, Any]) -> list[str]:
    """Every 1-D float observation field (no camera images, no particle state)."""
    spec = json.loads(resolve_spec(env_id, json.dumps(env_config)))
    return [
        f["name"]
        for f in spec["observation"]
        if f["dtype"] == "float32" and len(f["shape"]) == 1
    ]


def obs_size(env_id: str, env_config: dict[str, Any], obs_keys: Sequence[str]) -> int:
    """Length of the concatenated ``"observation"`` vector."""
    spec = json.loads(resolve_spec(env_id, json.dumps(env_config)))
    sizes = {f["name"]: int(f["shape"][0]) if f["shape"] else 1 for f in spec["observation"]}
    unknown = [k for k in obs_keys if k not in sizes]
    if unknown:
        raise ValueError(f"{env_id} has no observation fields {unknown}")
    return sum(sizes[k] for k in obs_keys)


def info_keys_for(env_id: str, env_config: dict[str, Any]) -> list[str]:
    """The reported info keys this env declares."""
    spec = json.loads(resolve_spec(env_id, json.dumps(env_config)))
    return [k for k in REPORTED_INFO if k in spec["info_keys"]]


class WorkerEnv(EchoEnv):
    """:class:`~echogym.torchrl.EchoEnv` with ``obs_keys`` concatenated into
    ``"observation"``, the episode return in ``"episode_reward"`` and its length in
    ``"step_count"``.

    The same keys, specs and values as ``TransformedEnv(EchoEnv(...),
    Compose(CatTensors(obs_keys, "observation", del_keys=True), RewardSum(),
    StepCounter()))`` (tests/test_torchrl.py compares them step by step), without the
    transforms' per-step tensordict plumbing: each step concatenates the fields straight
    from the shared-memory views (sorted by name, as ``CatTensors`` orders them) and builds
    one tensordict. ``"observation"`` is always a fresh tensor; the other observation
    fields (e.g. images) are copied too unless ``copy_observations=False`` (then they are
    views of the sample, as ``EchoEnv`` returns them, which a collector's batch does not
    keep: see :mod:`echogym.torchrl`; training reads only ``"observation"``).

    :meth:`step_and_maybe_reset` (what collectors call every step) takes a direct path
    for the plain case: ``EnvBase.step``'s generic checks are skipped (this env's output
    is complete: done keys, reward shape) and ``step_mdp`` is computed from torchrl's own
    key lists for this env; a batch with any env done, or any input the direct path does
    not handle (a ``"_step"`` mask, a preset ``"next"``, nested keys, dimension names, type
    checks, hooks), goes through torchrl's code.
    """

    #: Take the direct `step_and_maybe_reset` path where it applies (tests turn it off
    #: to compare with torchrl's generic path).
    fast_step = True

    def __init__(
        self,
        env_id: str,
        num_envs: int,
        obs_keys: Sequence[str],
        *,
        server: str | None = None,
        copy_observations: bool = False,
        info_keys: Sequence[str] | bool = (),
        **config: Any,
    ) -> None:
        self.obs_keys = sorted(obs_keys)  # CatTensors' default order
        super().__init__(
            env_id,
            num_envs,
            server=server,
            copy_observations=copy_observations,
            info_keys=info_keys,
            **config,
        )

    def _make_specs(self) -> None:
        super()._make_specs()
        n = self.num_envs
        fields = {f["name"]: f for f in self.echo_spec["observation"]}
        unknown = [k for k in self.obs_keys if k not in fields]
        if unknown:
            raise ValueError(f"{self.env_id} has no observation fields {unknown}")
        if not self.obs_keys:
            raise ValueError("obs_keys is empty: nothing to concatenate into 'observation'")
        dtypes = {fields[k]["dtype"] for k in self.obs_keys}
        if len(dtypes) != 1 or any(len(fields[k]["shape"]) != 1 for k in self.obs_keys):
            raise ValueError(f"obs_keys must be 1-D fields of one dtype: {self.obs_keys}")
        self._cat_index = [self._obs_names.index(k) for k in self.obs_keys]
        self._rest = [
            (i, name) for i, name in enumerate(self._obs_names) if name not in self.obs_keys
        ]
        size = sum(int(fields[k]["shape"][0]) for k in self.obs_keys)
        obs = self.observation_spec
        first = obs[self.obs_keys[0]]
        for key in self.obs_keys:
            del obs[key]
        obs["observation"] = Unbounded(shape=(n, size), dtype=first.dtype, device=self.device)
        # RewardSum and StepCounter declare their entries as observations and as state
        # (so `step_mdp` carries them to the next step's root, where `_step` reads them).
        episode = {
            "episode_reward": Unbounded(shape=(n, 1), dtype=torch.float32, device=self.device),
            "step_count": Bounded(
                low=0, high=torch.iinfo(torch.int64).max, shape=(n, 1), dtype=torch.int64,
                device=self.device,
            ),
        }
        obs.update({k: v.clone() for k, v in episode.items()})
        self.observation_spec = obs
        self.state_spec = Composite(episode, shape=(n,), device=self.device)
        self._mdp_keys: tuple[frozenset[str], tuple[str, ...]] | None = None

    def _flat_slot(self, slot: _Slot) -> list[torch.Tensor]:
        # The fields to concatenate, cached with the slot.
        if slot.extra is None:
            slot.extra = [slot.fields[i] for i in self._cat_index]
        return slot.extra

    def _entries(self, slot: _Slot, reward: bool) -> dict[str, Any]:
        out: dict[str, Any] = {"observation": torch.cat(self._flat_slot(slot), dim=-1)}
        copy = self.copy_observations
        for index, name in self._rest:
            tensor = slot.fields[index]
            out[name] = tensor.clone() if copy else tensor
        self._small_entries(slot, out, reward)
        return out

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        reset = tensordict.get("_reset", None) if tensordict is not None else None
        mask = None
        if reset is not None:
            mask = reset.reshape(self.num_envs).cpu().numpy().astype(bool)
        seeds, self._seeds = self._seeds, None
        out = self._entries(self._slot(self.lease.reset(mask, seeds)), reward=False)
        # RewardSum and StepCounter: zero where reset (everywhere without a mask), kept
        # where not.
        n = self.num_envs
        episode_reward = tensordict.get("episode_reward", None) if tensordict is not None else None
        step_count = tensordict.get("step_count", None) if tensordict is not None else None
        if reset is None:
            out["episode_reward"] = torch.zeros((n, 1), dtype=torch.float32)
            out["step_count"] = torch.zeros((n, 1), dtype=torch.int64)
        else:
            keep = ~reset.reshape(n, 1).cpu()
            out["episode_reward"] = (
                torch.zeros((n, 1), dtype=torch.float32)
                if episode_reward is None
                else torch.where(keep, episode_reward.cpu(), 0.0)
            )
            out["step_count"] = (
                torch.zeros((n, 1), dtype=torch.int64)
                if step_count is None
                else torch.where(keep, step_count.cpu(), 0)
            )
        return self._finish(out)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        out = self._entries(self._slot(self.lease.step(self._action_array(tensordict))),
                            reward=True)
        reward = out["reward"]
        episode_reward = tensordict.get("episode_reward", None)
        out["episode_reward"] = (
            reward.clone() if episode_reward is None else episode_reward.cpu() + reward
        )
        step_count = tensordict.get("step_count", None)
        out["step_count"] = (
            torch.ones_like(reward, dtype=torch.int64) if step_count is None
            else step_count.cpu() + 1
        )
        return self._finish(out)

    def _step_mdp_keys(self) -> tuple[frozenset[str], tuple[str, ...]] | None:
        """torchrl's ``step_mdp`` key lists for this env (the root entries it drops, the
        ``"next"`` entries it carries over), or ``None`` if any key is nested."""
        if self._mdp_keys is None:
            mdp = self._step_mdp
            drop, carry = mdp.exclude_from_root, mdp.keys_from_next
            if not mdp.keep_other or any(
                not isinstance(k, str) or v is not None
                for k, v in (*drop.items(), *carry.items())
            ):
                self._mdp_keys = (frozenset(), ())  # marks "not applicable"
            else:
                self._mdp_keys = (frozenset(drop), tuple(carry))
        return self._mdp_keys if self._mdp_keys[1] else None

    def step_and_maybe_reset(
        self, tensordict: TensorDictBase
    ) -> tuple[TensorDictBase, TensorDictBase]:
        keys = self._step_mdp_keys() if self.fast_step else None
        if (
            keys is None
            or type(tensordict) is not TensorDict
            or tensordict.batch_size != self.batch_size
            or (tensordict.device is not None and tensordict.device != self.device)
            or tensordict._has_names()
            or self.run_type_checks
            or self._post_step_mdp_hooks is not None
            or self.__dict__.get("_torchrl_native_autoreset", False)
            or self.__dict__.get("_compiled_step_and_maybe_reset", None) is not None
            or "_step" in tensordict.keys()
            or "next" in tensordict.keys()
        ):
            return super().step_and_maybe_reset(tensordict)
        # EnvBase.step: the output of `_step` is complete, so it only needs attaching.
        # (`_set_str(validated=True)` is what torchrl's own step_mdp uses to set entries
        # it built; tensordict is pinned to 0.14.x in pyproject.toml.)
        nxt = self._step(tensordict)
        tensordict._set_str("next", nxt, validated=True, inplace=False, non_blocking=False)
        # step_mdp: the root's entries but the dropped ones, then the carried ones of
        # "next" (absent ones skipped, as torchrl allows).
        drop, carry = keys
        root = tensordict.empty()
        for key, value in tensordict.items():
            if key not in drop:
                if not isinstance(value, torch.Tensor) and is_tensor_collection(value):
                    value = value.copy()
                root._set_str(key, value, validated=True, inplace=False, non_blocking=False)
        for key in carry:
            value = nxt._get_str(key, None)
            if value is not None:
                if not isinstance(value, torch.Tensor) and is_tensor_collection(value):
                    value = value.copy()
                root._set_str(key, value, validated=True, inplace=False, non_blocking=False)
        # maybe_reset: torchrl's own when any env is done (rare: episode ends).
        if nxt._get_str("done", None).any():
            root = self.maybe_reset(root)
        return tensordict, root


def build_env(
    env_id: str,
    num_envs: int,
    env_config: dict[str, Any],
    obs_keys: Sequence[str],
    server: str | None = None,
    copy_observations: bool = False,
) -> EnvBase:
    """One worker's env: ``num_envs`` server-side envs as a :class:`WorkerEnv`."""
    return WorkerEnv(
        env_id,
        num_envs,
        obs_keys,
        server=server,
        copy_observations=copy_observations,
        info_keys=info_keys_for(env_id, env_config),
        **env_config,
    )


def env_factory(
    env_id: str,
    num_envs: int,
    env_config: dict[str, Any],
    obs_keys: Sequence[str],
    server: str | None = None,
) -> Callable[[], EnvBase]:
    """A picklable factory of :func:`build_env` (zero-copy: collectors copy every step)."""
    return functools.partial(build_env, env_id, num_envs, dict(env_config), list(obs_keys), server)
