"""A calibration report's replays in the rerun viewer (``echogym view --calibration OUT``).

For every recording of ``echogym calibrate DATASET --out OUT`` (read with
:mod:`echogym.calibration`), on the ``replay_time`` timeline (seconds from the
recording's start), under ``calibration/<split>/<recording>/``:

* ``force`` — lines ``measured``, ``baseline``, ``calibrated`` (N);
* ``residual`` — ``measured − baseline`` and ``measured − calibrated`` (N);
* ``mismatch`` — 1 inside the report's worst mismatch spans of that recording, else 0
  (the spans' residual shares in ``calibration/spans``, a text log).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from echogym.calibration import load_replay, load_report
from echogym.rerun_log import import_rerun

__all__ = ["log_calibration"]


def _columns(rr: Any, values: np.ndarray) -> Any:
    rows, width = values.shape
    return rr.Scalars.columns(scalars=values.reshape(-1)).partition(np.full(rows, width))


def log_calibration(out: str | Path, recording: Any) -> int:
    """Log every replay of the report in ``out`` to ``recording``; the replays logged.

    Raises ``FileNotFoundError`` naming the file when ``out`` holds no report."""
    rr = import_rerun()
    out = Path(out)
    if not (out / "report.json").is_file():
        raise FileNotFoundError(f"{out / 'report.json'}: no calibration report (run echogym calibrate "
                                f"DATASET --out {out})")
    report = load_report(out)
    spans = report.get("mismatch", [])
    recording.log("calibration/spans", rr.TextLog(
        "\n".join(f"{s['recording']} {s['t_start']:.1f}-{s['t_end']:.1f} s: "
                  f"{100 * s['share']:.1f} % of the residual energy" for s in spans)), static=True)
    logged = 0
    # The split's recording lists; it also holds lists that are not recordings
    # (`protocols_not_in_test`), so the roles are named.
    for role in ("train", "validation", "test", "heldout"):
        for file in report["split"].get(role, []):
            replay = load_replay(out, str(file))
            if not replay:
                continue
            t = np.asarray(replay["t"])
            measured, baseline, calibrated = (np.asarray(replay[k]) for k in
                                              ("fz_measured", "fz_baseline", "fz_calibrated"))
            base = f"calibration/{role}/{Path(str(file)).stem}"
            time = [rr.TimeColumn("replay_time", duration=t)]
            inside = np.zeros_like(t)
            for s in spans:
                if Path(s["recording"]).stem == Path(str(file)).stem:
                    inside[(t >= s["t_start"]) & (t <= s["t_end"])] = 1.0
            series = {
                "force": (["measured", "baseline", "calibrated"],
                          np.column_stack([measured, baseline, calibrated])),
                "residual": (["measured − baseline", "measured − calibrated"],
                             np.column_stack([measured - baseline, measured - calibrated])),
                "mismatch": (["worst span"], inside[:, None]),
            }
            for name, (labels, values) in series.items():
                recording.log(f"{base}/{name}", rr.SeriesLines(names=labels), static=True)
                recording.send_columns(f"{base}/{name}", indexes=time, columns=_columns(rr, values))
            logged += 1
    return logged
