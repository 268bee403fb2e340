"""Episodes → a LeRobot dataset in the on-disk format ``LeRobotDataset`` of lerobot 0.4
loads (``codebase_version`` ``v3.0``)::

    meta/info.json                         fps, features (dtype, shape, names), paths
    meta/stats.json                        min, max, mean, std, count, q01…q99 per feature
    meta/tasks.parquet                     task string (index) → task_index
    meta/episodes/chunk-000/file-000.parquet   per episode: length, tasks, data file, rows
    data/chunk-000/file-NNN.parquet        one row per frame

Frames: ``observation.state`` (the low-dimensional observation fields concatenated, each
element named), ``observation.images.<camera>`` and ``observation.images.ultrasound``
(PNG in the parquet, LeRobot's ``image`` dtype; a grey B-mode image is stored as three
equal channels, as LeRobot's image pipeline expects RGB), ``action``, ``next.reward``,
``next.done``, and LeRobot's ``timestamp``, ``frame_index``, ``episode_index``,
``index``, ``task_index``. Depth images are left out (float maps have no image dtype).

An episode from the server's recorder (world-frame tip and force, no action) gives
``observation.state`` = tip position, velocity and ``observation.wrench`` = force,
torque; it has no ``action`` or reward."""

from __future__ import annotations

import io
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from echogym.robotdata.episodes import Episode, EpisodeSource
from echogym.robotdata.errors import ExportError

__all__ = ["CODEBASE_VERSION", "export_lerobot", "state_layout"]

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000
DATA_FILE_MB = 100
#: Element names of the observation fields LeRobot users look for by name.
FIELD_NAMES = {
    "probe_pose": ["x", "y", "z", "qx", "qy", "qz", "qw"],
    "probe_vel": ["vx", "vy", "vz", "wx", "wy", "wz"],
    "ft": ["fx", "fy", "fz", "tx", "ty", "tz"],
    "tip": ["x", "y", "z"],
    "velocity": ["vx", "vy", "vz"],
    "force": ["fx", "fy", "fz"],
    "torque": ["tx", "ty", "tz"],
}
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)


def _is_image(array: np.ndarray) -> bool:
    return array.dtype == np.uint8 and array.ndim in (3, 4)


def _is_depth(name: str) -> bool:
    return name.endswith("_depth")


def state_layout(episode: Episode) -> tuple[list[str], list[str], dict[str, list[str]]]:
    """(state fields, image fields, extra vector features) of an episode, and names."""
    if episode.frames == "world":
        return ["tip", "velocity"], [], {"observation.wrench": ["force", "torque"]}
    state, images = [], []
    for name, array in episode.fields.items():
        if _is_image(array):
            images.append(name)
        elif not _is_depth(name) and array.ndim <= 2:
            state.append(name)
    return state, images, {}


def _element_names(field: str, size: int) -> list[str]:
    names = FIELD_NAMES.get(field)
    if names and len(names) == size:
        return [f"{field}.{n}" for n in names]
    return [f"{field}.{i}" for i in range(size)]


def _vector(episode: Episode, fields: list[str]) -> np.ndarray:
    parts = [episode.fields[f].reshape(episode.length, -1) for f in fields if f in episode.fields]
    return np.hstack(parts).astype(np.float32)


def _image_key(name: str) -> str:
    return "observation.images." + (name[:-4] if name.endswith("_rgb") else name)


def _png(frame: np.ndarray) -> bytes:
    from PIL import Image

    if frame.ndim == 2:
        frame = np.repeat(frame[:, :, None], 3, axis=2)
    buffer = io.BytesIO()
    Image.fromarray(frame).save(buffer, format="PNG", compress_level=1)
    return buffer.getvalue()


def _stats(values: np.ndarray) -> dict:
    """LeRobot's per-feature statistics over axis 0 (images: per channel, in [0, 1])."""
    values = np.asarray(values, dtype=np.float64)
    out = {"min": values.min(axis=0), "max": values.max(axis=0), "mean": values.mean(axis=0),
           "std": values.std(axis=0), "count": np.array([len(values)])}
    for q in QUANTILES:
        out[f"q{int(round(q * 100)):02d}"] = np.quantile(values, q, axis=0)
    return {k: v.tolist() for k, v in out.items()}


def _image_stats(frames: np.ndarray) -> dict:
    """Per-channel statistics of uint8 images ``[T, h, w(, 3)]`` as ``[3, 1, 1]`` lists."""
    if frames.ndim == 3:
        frames = np.repeat(frames[..., None], 3, axis=3)
    step = max(1, len(frames) // 100)  # LeRobot samples frames for image stats too
    pixels = frames[::step].reshape(-1, 3).astype(np.float64) / 255.0
    stats = _stats(pixels)
    stats = {k: (np.asarray(v).reshape(3, 1, 1).tolist() if k != "count" else [len(frames)])
             for k, v in stats.items()}
    return stats


def _tasks_table(tasks: list[str]) -> pa.Table:
    """``meta/tasks.parquet`` as pandas writes it: task_index, the task string as index."""
    table = pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()),
                      "__index_level_0__": pa.array(tasks, pa.large_string())})
    pandas_meta = {
        "index_columns": ["__index_level_0__"],
        "column_indexes": [{"name": None, "field_name": None, "pandas_type": "unicode",
                            "numpy_type": "str", "metadata": {"encoding": "UTF-8"}}],
        "columns": [
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64",
             "numpy_type": "int64", "metadata": None},
            {"name": None, "field_name": "__index_level_0__", "pandas_type": "object",
             "numpy_type": "str", "metadata": None}],
        "attributes": {}, "creator": {"library": "pyarrow", "version": pa.__version__},
        "pandas_version": "2.2.0"}
    return table.replace_schema_metadata({b"pandas": json.dumps(pandas_meta).encode()})


def export_lerobot(source: EpisodeSource, out: str | Path, robot_type: str | None = None) -> Path:
    """Write ``source``'s episodes as a LeRobot dataset at ``out`` (a new folder; written
    beside it and renamed into place, so a failure leaves nothing)."""
    out = Path(out)
    if out.exists():
        raise ExportError(out, "exists; LeRobot datasets go to a new folder")
    episodes = source.episodes
    if not episodes:
        raise ExportError(source.path, "no episodes to export")
    first = episodes[0]
    state_fields, image_fields, extra = state_layout(first)
    state_names = [n for f in state_fields if f in first.fields
                   for n in _element_names(f, first.fields[f].reshape(first.length, -1).shape[1])]
    features: dict[str, dict] = {
        "observation.state": {"dtype": "float32", "shape": [len(state_names)], "names": state_names}}
    for key, fields in extra.items():
        names = [n for f in fields if f in first.fields for n in _element_names(f, 3)]
        features[key] = {"dtype": "float32", "shape": [len(names)], "names": names}
    for name in image_fields:
        shape = first.fields[name].shape[1:]
        h, w = shape[0], shape[1]
        features[_image_key(name)] = {"dtype": "image", "shape": [h, w, 3],
                                      "names": ["height", "width", "channels"]}
    if first.action is not None:
        features["action"] = {"dtype": "float32", "shape": [first.action.shape[1]],
                              "names": [f"action.{i}" for i in range(first.action.shape[1])]}
    if first.reward is not None:
        features["next.reward"] = {"dtype": "float32", "shape": [1], "names": None}
        features["next.done"] = {"dtype": "bool", "shape": [1], "names": None}
    for key in ("timestamp",):
        features[key] = {"dtype": "float32", "shape": [1], "names": None}
    for key in ("frame_index", "episode_index", "index", "task_index"):
        features[key] = {"dtype": "int64", "shape": [1], "names": None}

    tasks: list[str] = []
    temp = out.with_name(f".{out.name}.partial-{os.getpid()}")
    shutil.rmtree(temp, ignore_errors=True)
    (temp / "meta" / "episodes" / "chunk-000").mkdir(parents=True)
    data_dir = temp / "data" / "chunk-000"
    data_dir.mkdir(parents=True)
    try:
        writer: pq.ParquetWriter | None = None
        file_index, file_bytes, index = 0, 0, 0
        rows_per_episode: list[dict] = []
        columns_all: dict[str, list[np.ndarray]] = {k: [] for k in features
                                                    if features[k]["dtype"] != "image"}
        image_stats: dict[str, list[dict]] = {}
        for k, ep in enumerate(episodes):
            task = ep.task or source.env_id or "echogym episode"
            if task not in tasks:
                tasks.append(task)
            n = ep.length
            cols: dict[str, np.ndarray] = {"observation.state": _vector(ep, state_fields)}
            if cols["observation.state"].shape[1] != len(state_names):
                raise ExportError(source.path, f"episode {k} has another observation layout than "
                                  "the first", where="observation.state")
            for key, fields in extra.items():
                cols[key] = _vector(ep, fields)
            if ep.action is not None and "action" in features:
                cols["action"] = ep.action.astype(np.float32).reshape(n, -1)
            if ep.reward is not None and "next.reward" in features:
                cols["next.reward"] = ep.reward.astype(np.float32)
                done = np.zeros(n, bool)
                done[-1] = ep.terminated or ep.truncated
                cols["next.done"] = done
            cols["timestamp"] = ep.t.astype(np.float32)
            cols["frame_index"] = np.arange(n, dtype=np.int64)
            cols["episode_index"] = np.full(n, k, np.int64)
            cols["index"] = np.arange(index, index + n, dtype=np.int64)
            cols["task_index"] = np.full(n, tasks.index(task), np.int64)
            arrays = {}
            for key, values in cols.items():
                columns_all[key].append(values)
                if values.ndim == 2:
                    arrays[key] = pa.FixedSizeListArray.from_arrays(
                        pa.array(values.reshape(-1)), values.shape[1])
                else:
                    arrays[key] = pa.array(values)
            for name in image_fields:
                frames = ep.fields[name]
                image_stats.setdefault(_image_key(name), []).append(_image_stats(frames))
                arrays[_image_key(name)] = pa.array(
                    [{"bytes": _png(f), "path": None} for f in frames],
                    pa.struct([("bytes", pa.binary()), ("path", pa.string())]))
            table = pa.table({key: arrays[key] for key in features if key in arrays})
            if writer is not None and file_bytes > DATA_FILE_MB * 1e6:
                writer.close()
                writer, file_index, file_bytes = None, file_index + 1, 0
            if writer is None:
                writer = pq.ParquetWriter(data_dir / f"file-{file_index:03d}.parquet", table.schema)
            writer.write_table(table)
            file_bytes += table.nbytes
            rows_per_episode.append({
                "episode_index": k, "tasks": [task], "length": n,
                "data/chunk_index": 0, "data/file_index": file_index,
                "dataset_from_index": index, "dataset_to_index": index + n,
                "meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0})
            index += n
        if writer is not None:
            writer.close()
        pq.write_table(pa.Table.from_pylist(rows_per_episode),
                       temp / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
        pq.write_table(_tasks_table(tasks), temp / "meta" / "tasks.parquet")
        stats = {}
        for key, parts in columns_all.items():
            values = np.concatenate(parts)
            stats[key] = _stats(values.reshape(len(values), -1))
        for key, per_episode in image_stats.items():
            stats[key] = _merge_image_stats(per_episode)
        (temp / "meta" / "stats.json").write_text(json.dumps(stats, indent=1))
        info = {
            "codebase_version": CODEBASE_VERSION, "robot_type": robot_type,
            "total_episodes": len(episodes), "total_frames": index, "total_tasks": len(tasks),
            "chunks_size": CHUNKS_SIZE, "data_files_size_in_mb": DATA_FILE_MB,
            "video_files_size_in_mb": 200, "fps": int(round(source.fps)),
            "splits": {"train": f"0:{len(episodes)}"},
            "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
            "video_path": None, "features": features,
        }
        (temp / "meta" / "info.json").write_text(json.dumps(info, indent=4))
        temp.rename(out)
    except BaseException:
        shutil.rmtree(temp, ignore_errors=True)
        raise
    return out


def _merge_image_stats(per_episode: list[dict]) -> dict:
    """Count-weighted mean of the episodes' image statistics (min/max exact, quantiles
    averaged as LeRobot's aggregation does)."""
    counts = np.array([s["count"][0] for s in per_episode], float)
    weights = counts / counts.sum()
    out = {}
    for key in per_episode[0]:
        stacked = np.array([s[key] for s in per_episode], float)
        if key == "min":
            out[key] = stacked.min(axis=0).tolist()
        elif key == "max":
            out[key] = stacked.max(axis=0).tolist()
        elif key == "count":
            out[key] = [int(counts.sum())]
        else:
            out[key] = np.tensordot(weights, stacked, axes=1).tolist()
    return out
