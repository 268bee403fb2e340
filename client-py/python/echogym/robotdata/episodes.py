"""Episodes to export, read from either of echogym's recording formats:

- ``echogym-episodes/1``, what :class:`~echogym.robotdata.recorder.RecordEpisodes` writes
  from a running env or vector env: ``episodes.json`` plus one ``.npz`` per episode with
  every observation field (``obs/<field>``), ``action``, ``reward``, ``terminated``,
  ``truncated`` and the env's numeric info (``info/<key>``), one row per step (the
  observation before the step, the action taken, what the step returned);
- ``echogym-recordings/1``, the server's recorder output (``record={"dir": ...}``): the
  probe tip's position, velocity, force and torque every physics step, world frame.

Both become :class:`Episode`: time stamps and named arrays, ``[T, ...]`` each."""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from echogym.robotdata.errors import ExportError

__all__ = ["EPISODES_FORMAT", "Episode", "read_episodes"]

EPISODES_FORMAT = "echogym-episodes/1"
RECORDINGS_FORMAT = "echogym-recordings/1"


@dataclass
class Episode:
    """One episode: ``t [T]`` seconds from its start, ``fields`` (observation fields by
    name; images ``uint8 [T, h, w, 3]`` or ``[T, h, w]``), ``action [T, A]`` or ``None``,
    ``reward [T]`` or ``None``, and where it came from. ``frames`` says how the pose and
    the wrench are expressed: ``"sensor"`` (``probe_pose`` x, y, z, qx, qy, qz, qw and
    ``ft`` in the probe's own frame, an env's observations) or ``"world"`` (``tip`` and
    ``force``/``torque`` in the world, the recorder's CSV)."""

    index: int
    t: np.ndarray
    fields: dict[str, np.ndarray]
    action: np.ndarray | None = None
    reward: np.ndarray | None = None
    terminated: bool = False
    truncated: bool = False
    task: str = ""
    frames: str = "sensor"
    info: dict[str, np.ndarray] = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    @property
    def length(self) -> int:
        return len(self.t)


@dataclass
class EpisodeSource:
    """Episodes and what they share: ``fps`` (the env's control rate or the recording's
    median rate), the env id, field layout from the env's spec."""

    episodes: list[Episode]
    fps: float
    env_id: str
    spec: dict
    path: Path


def read_episodes(path: str | Path) -> EpisodeSource:
    """The episodes in ``path``: an ``echogym-episodes/1`` or ``echogym-recordings/1``
    folder (or a folder holding the server recorder's dataset folders, read in order)."""
    path = Path(path)
    meta_path = next((path / n for n in ("episodes.json", "dataset.json") if (path / n).is_file()), None)
    if meta_path is None:
        nested = sorted(p.parent for p in path.glob("*/dataset.json"))
        if not nested:
            raise ExportError(path, "neither episodes.json (echogym-episodes/1) nor dataset.json "
                              "(echogym-recordings/1) here or one level down")
        sources = [read_episodes(p) for p in nested]
        episodes = [e for s in sources for e in s.episodes]
        for k, e in enumerate(episodes):
            e.index = k
        return EpisodeSource(episodes, sources[0].fps, sources[0].env_id, sources[0].spec, path)
    try:
        meta = json.loads(meta_path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ExportError(meta_path, f"cannot read: {exc}") from None
    fmt = meta.get("format")
    if fmt == EPISODES_FORMAT:
        return _read_episode_folder(path, meta)
    if fmt == RECORDINGS_FORMAT:
        return _read_recordings(path, meta)
    raise ExportError(meta_path, f"unknown format {fmt!r}; expected {EPISODES_FORMAT!r} or "
                      f"{RECORDINGS_FORMAT!r}", where="format")


def _read_episode_folder(path: Path, meta: dict) -> EpisodeSource:
    episodes = []
    dt = 1.0 / float(meta["fps"])
    for k, entry in enumerate(meta["episodes"]):
        file = path / entry["file"]
        try:
            data = np.load(file)
        except (OSError, ValueError) as exc:
            raise ExportError(file, f"cannot read the episode: {exc}") from None
        with data:
            fields = {key[4:]: data[key] for key in data.files if key.startswith("obs/")}
            info = {key[5:]: data[key] for key in data.files if key.startswith("info/")}
            action, reward = data["action"], data["reward"]
        episodes.append(Episode(k, np.arange(len(reward)) * dt, fields, action, reward,
                                bool(entry.get("terminated")), bool(entry.get("truncated")),
                                entry.get("task", ""), "sensor", info, entry))
    return EpisodeSource(episodes, float(meta["fps"]), meta.get("env_id", ""), meta.get("spec", {}), path)


def _read_recordings(path: Path, meta: dict) -> EpisodeSource:
    episodes = []
    rates = []
    for k, entry in enumerate(meta.get("recordings", [])):
        file = path / entry["file"]
        try:
            with file.open(newline="") as handle:
                rows = list(csv.reader(handle))
        except OSError as exc:
            raise ExportError(file, f"cannot read the recording: {exc}") from None
        header = [h.strip() for h in rows[0]]
        try:
            values = np.array(rows[1:], dtype=float)
        except ValueError as exc:
            raise ExportError(file, f"not numbers: {exc}") from None

        def cols(*names: str) -> np.ndarray | None:
            if not all(n in header for n in names):
                return None
            return values[:, [header.index(n) for n in names]]

        for needed in ("t", "px", "py", "pz", "fx", "fy", "fz"):
            if needed not in header:
                raise ExportError(file, "missing column", where=needed)
        t = values[:, header.index("t")]
        fields = {"tip": cols("px", "py", "pz"), "force": cols("fx", "fy", "fz")}
        for name, names in (("velocity", ("vx", "vy", "vz")), ("torque", ("tx", "ty", "tz"))):
            got = cols(*names)
            if got is not None:
                fields[name] = got
        if len(t) > 1:
            rates.append(1.0 / float(np.median(np.diff(t))))
        task = f"{entry.get('protocol', 'press')} at {entry.get('site', '?')}"
        episodes.append(Episode(k, t - t[0], {n: v for n, v in fields.items() if v is not None},
                                task=task, frames="world", meta=entry))
    if not episodes:
        raise ExportError(path, "the dataset lists no recordings")
    return EpisodeSource(episodes, float(np.median(rates)) if rates else 0.0,
                         meta.get("description", ""), {}, path)
