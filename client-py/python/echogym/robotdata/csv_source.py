"""Reading a robot's own CSV log with a column mapping (:class:`~.options.CsvColumns`):
units converted to SI, orientation from quaternion or roll-pitch-yaw columns or fixed.

Rows may hold the wrench and the pose together, or interleave them with empty cells (a
merged export of two topics): a series takes the rows where all of its cells are
filled. A cell that is filled but not a number, ``nan`` or ``inf`` is refused."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from echogym.robotdata.checks import check_finite, check_increasing
from echogym.robotdata.errors import LogFormatError, MissingColumnError, NonFiniteError
from echogym.robotdata.options import (
    FORCE_UNITS,
    LENGTH_UNITS,
    TIME_UNITS,
    TORQUE_UNITS,
    ImportOptions,
)
from echogym.robotdata.rotations import matrix_from_rpy, quaternion_from_matrix
from echogym.robotdata.series import PoseSeries, SourceLog, WrenchSeries

__all__ = ["read_csv"]


def read_csv(path: str | Path, options: ImportOptions) -> SourceLog:
    """The CSV at ``path`` as wrench and pose series, per ``options.csv``."""
    path = Path(path)
    c = options.csv
    try:
        with path.open(newline="") as handle:
            rows = list(csv.reader(handle, delimiter=c.delimiter))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise LogFormatError(path, f"cannot read the CSV: {exc}") from None
    if not rows:
        raise LogFormatError(path, "empty file")
    header = [h.strip() for h in rows[0]]
    body = rows[1:]

    def columns(names: list[str], key: str) -> np.ndarray:
        """``[rows, len(names)]`` floats, NaN where a cell is empty."""
        out = np.full((len(body), len(names)), np.nan)
        for j, name in enumerate(names):
            if name not in header:
                raise MissingColumnError(path, f"no such column (csv.{key}); header: "
                                         f"{','.join(header)}", where=name)
            col = header.index(name)
            for i, row in enumerate(body):
                text = row[col].strip() if col < len(row) else ""
                if not text:
                    continue
                try:
                    value = float(text)
                except ValueError:
                    raise NonFiniteError(path, f"row {i + 2}: not a number: {text!r}",
                                         where=name) from None
                if not np.isfinite(value):
                    raise NonFiniteError(path, f"row {i + 2}: {text}", where=name)
                out[i, j] = value
        return out

    t_all = columns([c.time], "time")[:, 0] * TIME_UNITS[c.time_unit]
    if np.isnan(t_all).any():
        row = int(np.argmax(np.isnan(t_all)))
        raise NonFiniteError(path, f"row {row + 2}: no time", where=c.time)
    position = columns(c.position, "position") * LENGTH_UNITS[c.position_unit]
    force = columns(c.force, "force") * FORCE_UNITS[c.force_unit]
    torque = (columns(c.torque, "torque") * TORQUE_UNITS[c.torque_unit]
              if c.torque else None)
    if c.quaternion:
        orientation = columns(c.quaternion, "quaternion")
    elif c.rpy:
        angles = columns(c.rpy, "rpy")
        orientation = np.full((len(body), 4), np.nan)
        ok = ~np.isnan(angles).any(axis=1)
        if ok.any():
            orientation[ok] = quaternion_from_matrix(np.array([matrix_from_rpy(a) for a in angles[ok]]))
    else:
        fixed = quaternion_from_matrix(matrix_from_rpy(c.orientation_rpy))
        orientation = np.where(np.isnan(position[:, :1]), np.nan, fixed[None, :])
    has_pose = ~np.isnan(np.hstack([position, orientation])).any(axis=1)
    wrench_cells = force if torque is None else np.hstack([force, torque])
    has_wrench = ~np.isnan(wrench_cells).any(axis=1)
    force_name = ",".join(c.force)
    pose_name = ",".join(c.position)
    for mask, name in ((has_wrench, force_name), (has_pose, pose_name)):
        if not mask.any():
            raise MissingColumnError(path, "no row has all of these columns filled", where=name)
    t_w, t_p = t_all[has_wrench], t_all[has_pose] + options.pose_time_offset_s
    check_increasing(path, c.time, t_w)
    check_increasing(path, c.time, t_p)
    check_finite(path, force_name, t_w, wrench_cells[has_wrench])
    frame = options.wrench_frame if options.wrench_frame != "auto" else "tool"
    return SourceLog(
        path=str(path),
        wrench=WrenchSeries(t_w, force[has_wrench], torque[has_wrench] if torque is not None
                            else None, frame, force_name),
        pose=PoseSeries(t_p, position[has_pose], orientation[has_pose], "world", pose_name),
        provenance={"file": str(path), "kind": "csv",
                    "columns": {"time": c.time, "position": c.position, "force": c.force,
                                "torque": c.torque, "quaternion": c.quaternion, "rpy": c.rpy},
                    "units": {"time": c.time_unit, "position": c.position_unit,
                              "force": c.force_unit, "torque": c.torque_unit},
                    "orientation": ("quaternion columns" if c.quaternion else "rpy columns"
                                    if c.rpy else f"fixed rpy {c.orientation_rpy}"),
                    "rows": len(body), "wrench_rows": int(has_wrench.sum()),
                    "pose_rows": int(has_pose.sum())},
    )
