"""Recording episodes from a running env for export: :class:`RecordEpisodes` wraps a
gymnasium env, :class:`RecordVectorEpisodes` a vector env (same-step autoreset, as
echogym's). Each step copies the observation before the step, the action, the reward,
the end flags and the numeric info into the episode's buffer; a finished episode is
written as one ``.npz`` (``echogym-episodes/1``, see :mod:`.episodes`). Envs that are not
wrapped pay nothing. The folder appears when the wrapper is closed: files go to a
temporary folder beside it, renamed into place at the end."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

from echogym.robotdata.episodes import EPISODES_FORMAT
from echogym.robotdata.errors import ExportError

__all__ = ["EpisodeWriter", "RecordEpisodes", "RecordVectorEpisodes"]


class EpisodeWriter:
    """Buffers steps per env slot and writes finished episodes to ``out``."""

    def __init__(self, out: str | Path, spec: dict, task: str = "") -> None:
        self.out = Path(out)
        if self.out.exists():
            raise ExportError(self.out, "exists; episodes go to a new folder")
        self.temp = self.out.with_name(f".{self.out.name}.partial-{os.getpid()}")
        shutil.rmtree(self.temp, ignore_errors=True)
        self.temp.mkdir(parents=True)
        self.spec = spec
        self.task = task or spec.get("env_id", "")
        self.fps = 1.0 / float(spec.get("dt_s") or 0.02)
        self.entries: list[dict] = []
        self._buffers: dict[int, dict[str, list]] = {}

    def add(self, slot: int, obs: dict[str, np.ndarray], action: Any, reward: float,
            info: dict[str, Any]) -> None:
        """One step of env ``slot``: ``obs`` is the observation the action was taken in."""
        buf = self._buffers.setdefault(slot, {"obs": [], "action": [], "reward": [], "info": []})
        buf["obs"].append({k: np.array(v, copy=True) for k, v in obs.items()})
        buf["action"].append(np.array(action, dtype=np.float32, copy=True))
        buf["reward"].append(float(reward))
        buf["info"].append({k: float(v) for k, v in info.items()
                            if np.isscalar(v) and not isinstance(v, (str, bytes))})

    def end(self, slot: int, terminated: bool, truncated: bool) -> None:
        """Write env ``slot``'s buffered episode (if it has a step)."""
        buf = self._buffers.pop(slot, None)
        if not buf or not buf["reward"]:
            return
        arrays: dict[str, np.ndarray] = {
            "action": np.stack(buf["action"]),
            "reward": np.asarray(buf["reward"], np.float32),
        }
        for key in buf["obs"][0]:
            arrays[f"obs/{key}"] = np.stack([o[key] for o in buf["obs"]])
        keys = set().union(*buf["info"])
        for key in sorted(keys):
            arrays[f"info/{key}"] = np.asarray([i.get(key, np.nan) for i in buf["info"]], np.float32)
        file = f"episode_{len(self.entries):06d}.npz"
        np.savez_compressed(self.temp / file, **arrays)
        self.entries.append({"file": file, "length": len(buf["reward"]), "env_index": slot,
                             "terminated": bool(terminated), "truncated": bool(truncated),
                             "task": self.task})

    def close(self) -> Path:
        """Drop unfinished episodes, write ``episodes.json`` and move the folder into place."""
        self._buffers.clear()
        meta = {"format": EPISODES_FORMAT, "env_id": self.spec.get("env_id", ""), "fps": self.fps,
                "spec": {k: self.spec.get(k) for k in ("env_id", "observation", "action",
                                                        "info_keys", "dt_s", "config")},
                "episodes": self.entries}
        (self.temp / "episodes.json").write_text(json.dumps(meta, indent=1) + "\n")
        self.temp.rename(self.out)
        return self.out


class RecordEpisodes(gymnasium.Wrapper):
    """Record a single env's episodes into ``out`` (see the module doc). ``task`` is the
    language instruction stored with each episode (LeRobot's ``task``)."""

    def __init__(self, env: gymnasium.Env, out: str | Path, task: str = "") -> None:
        super().__init__(env)
        spec = getattr(env.unwrapped, "echo_spec", {})
        self.writer = EpisodeWriter(out, spec, task)
        self._obs: dict | None = None

    def reset(self, **kwargs: Any):
        if self._obs is not None:
            self.writer.end(0, False, True)  # a reset mid-episode cuts it
        obs, info = self.env.reset(**kwargs)
        self._obs = obs
        return obs, info

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if self._obs is not None:
            self.writer.add(0, self._obs, action, reward, info)
            if terminated or truncated:
                self.writer.end(0, terminated, truncated)
        self._obs = None if terminated or truncated else obs
        return obs, reward, terminated, truncated, info

    def close(self) -> None:
        self.writer.close()
        super().close()


class RecordVectorEpisodes(gymnasium.vector.VectorWrapper):
    """Record every sub-env's episodes of a vector env with same-step autoreset (an
    ended env's next observation already starts its new episode)."""

    def __init__(self, env: gymnasium.vector.VectorEnv, out: str | Path, task: str = "") -> None:
        super().__init__(env)
        mode = env.metadata.get("autoreset_mode")
        if mode is not None and mode != gymnasium.vector.AutoresetMode.SAME_STEP:
            raise ExportError(out, f"records vector envs with same-step autoreset, not {mode}",
                              where="autoreset_mode")
        spec = getattr(env.unwrapped, "echo_spec", {})
        self.writer = EpisodeWriter(out, spec, task)
        self._obs: dict | None = None

    def reset(self, **kwargs: Any):
        obs, info = self.env.reset(**kwargs)
        for slot in range(self.num_envs):
            self.writer.end(slot, False, True)
        self._obs = {k: np.array(v, copy=True) for k, v in obs.items()}
        return obs, info

    def step(self, actions: Any):
        obs, reward, terminated, truncated, info = self.env.step(actions)
        if self._obs is not None:
            final_info = info.get("final_info")
            for slot in range(self.num_envs):
                if final_info is not None and final_info[slot] is not None:
                    slot_info = final_info[slot]  # the ended episode's, not the new one's
                else:
                    slot_info = {k: v[slot] for k, v in info.items()
                                 if isinstance(v, np.ndarray) and v.shape[:1] == (self.num_envs,)
                                 and not k.startswith("_") and v.dtype != object}
                self.writer.add(slot, {k: v[slot] for k, v in self._obs.items()}, actions[slot],
                                reward[slot], slot_info)
                if terminated[slot] or truncated[slot]:
                    self.writer.end(slot, bool(terminated[slot]), bool(truncated[slot]))
        self._obs = {k: np.array(v, copy=True) for k, v in obs.items()}
        return obs, reward, terminated, truncated, info

    def close(self, **kwargs: Any) -> None:
        self.writer.close()
        super().close(**kwargs)
