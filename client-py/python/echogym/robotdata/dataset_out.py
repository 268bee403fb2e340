"""Writing an ``echogym-recordings/1`` dataset (see server/src/recordings/mod.rs) atomically:
everything goes into a temporary folder beside the target, renamed into place at the end,
so a failed import leaves nothing half-written."""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from echogym.robotdata.errors import RobotDataError

__all__ = ["FORMAT", "RecordingOut", "write_dataset"]

FORMAT = "echogym-recordings/1"


@dataclass
class RecordingOut:
    """One CSV: time [s], tip position [m], force [N] (world, the body's force on the
    probe), torque [N·m] or ``None``; ``entry`` is its ``dataset.json`` entry (``file``,
    ``site``, ``protocol`` and any further keys)."""

    t: np.ndarray
    position: np.ndarray
    force: np.ndarray
    torque: np.ndarray | None
    entry: dict


def write_dataset(out: str | Path, meta: dict, recordings: list[RecordingOut]) -> Path:
    """Write ``meta`` (``dataset.json`` without ``format`` and ``recordings``) and the
    recordings to ``out``, which must not exist or be an empty folder."""
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise RobotDataError(out, "exists and is not an empty folder; choose another --out")
    out.parent.mkdir(parents=True, exist_ok=True)
    temp = out.with_name(f".{out.name}.partial-{os.getpid()}")
    shutil.rmtree(temp, ignore_errors=True)
    temp.mkdir()
    try:
        for rec in recordings:
            columns = [rec.t[:, None], rec.position, rec.force]
            header = "t,px,py,pz,fx,fy,fz"
            if rec.torque is not None:
                columns.append(rec.torque)
                header += ",tx,ty,tz"
            np.savetxt(temp / rec.entry["file"], np.hstack(columns), delimiter=",",
                       header=header, comments="", fmt="%.9g")
        document = {"format": FORMAT, **meta, "recordings": [r.entry for r in recordings]}
        (temp / "dataset.json").write_text(json.dumps(document, indent=2) + "\n")
        if out.exists():
            out.rmdir()
        temp.rename(out)
    except BaseException:
        shutil.rmtree(temp, ignore_errors=True)
        raise
    return out
