"""Reading what ``echogym calibrate DATASET --out OUT`` wrote: the calibrated scene
(``OUT/calibrated.toml``) as env config, the report (``OUT/report.json``), the replay of
each recording (``OUT/replay/*.csv``) and the thesis's regression points
(``OUT/thesis_method.csv``).

Plain data only (dicts and lists of floats); the figures drawn from it are an
application, :mod:`echogym.apps.calibration_plots`.
"""

from __future__ import annotations

import csv
import json
import tomllib
from pathlib import Path
from typing import Any

__all__ = ["load_calibration", "load_replay", "load_report", "load_thesis_method"]

#: The keys of ``calibrated.toml`` that are env config.
SCENE_KEYS = ("torso", "breathing", "ft_sensor")


def load_calibration(path: str | Path) -> dict[str, Any]:
    """The env config keys (``torso``, ``breathing``, ``ft_sensor``) of a
    ``calibrated.toml``, e.g. ``gym.make("echogym/UltrasoundScan-v0", **load_calibration(p))``."""
    with open(path, "rb") as f:
        scene = tomllib.load(f)
    return {k: scene[k] for k in SCENE_KEYS if k in scene}


def load_report(out: str | Path) -> dict[str, Any]:
    """``OUT/report.json``: the split, the baseline, the effects named and rejected, the
    mismatch shares, the improvement on the held-out recordings, the thesis's method."""
    return json.loads((Path(out) / "report.json").read_text())


def load_replay(out: str | Path, recording: str) -> dict[str, list[float]]:
    """The replay of one recording (a file name from the report's split): a column per
    series, ``t`` [s] and ``fz_measured``/``fz_baseline``/``fz_calibrated`` [N] among them
    (``fx_*`` and ``fy_*`` the same for the sideways force)."""
    # A segment of a file cut at a gap is listed as `file.csv#k`, replayed to `file#k.csv`
    # (server/src/calibrate/report.rs).
    file, _, segment = recording.partition("#")
    stem = Path(file).stem + (f"#{segment}" if segment else "")
    with open(Path(out) / "replay" / f"{stem}.csv") as f:
        rows = list(csv.DictReader(f))
    return {k: [float(r[k]) for r in rows] for k in rows[0]} if rows else {}


def load_thesis_method(out: str | Path) -> dict[str, tuple[list[float], list[float]]]:
    """The thesis's regression points per site: ``(v/r [1/s], F/r [N/m])``."""
    points: dict[str, tuple[list[float], list[float]]] = {}
    with open(Path(out) / "thesis_method.csv") as f:
        for row in csv.DictReader(f):
            xs, ys = points.setdefault(row["site"], ([], []))
            xs.append(float(row["v_over_r"]))
            ys.append(float(row["f_over_r"]))
    return points
