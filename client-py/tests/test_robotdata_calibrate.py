"""A real-world-style log imports and calibrates: the independent generator's session
(tests/independent_data/generate.py: Hunt–Crossley contact on a curved body, coloured
sensor noise, a concealed sensor bias) rewritten as a robot's own logger would write it —
one CSV per trial at 60 Hz with ±30 % stamp jitter, a dropped half second in every third
file, millimetres and milliseconds, the flange's pose 11 cm above the tip, and the wrench
in the sensor frame with the probe's 0.25 kg in it. `echogym import` turns it into a
dataset with the generator's sites, on which `echogym calibrate` finds the concealed bias.

The calibration takes minutes (≈ 4 unloaded on 2 cores, far longer on a shared machine),
so this test is deselected by default
(marker `calibrate_e2e`; run it with `-m calibrate_e2e`)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import robot_logs as R
from echogym import _native
from echogym.robotdata import import_logs, load_mapping

REPO = Path(__file__).resolve().parents[2]
GENERATOR = REPO / "tests" / "independent_data" / "generate.py"
MAPPING = """
[csv]
time = "stamp_ms"
time_unit = "ms"
position = ["x_mm", "y_mm", "z_mm"]
position_unit = "mm"
force = ["Fx", "Fy", "Fz"]

[probe]
tool_offset = [0.0, 0.0, 0.11]
mass = 0.25
"""


def robot_csv(source: Path, session_time_s: float, out: Path, gap: bool, seed: int) -> None:
    """One generator recording as the robot's logger writes it (see the module doc)."""
    data = np.genfromtxt(source, delimiter=",", names=True)
    rng = np.random.default_rng(seed)
    t = data["t"]
    stamps = R.jittered_stamps(t[0], t[-1], 60.0, 0.3, rng)
    if gap:
        middle = (t[0] + t[-1]) / 2
        stamps = stamps[(stamps < middle) | (stamps > middle + 0.5)]
    tip = np.stack([np.interp(stamps, t, data[k]) for k in ("px", "py", "pz")], axis=1)
    force = np.stack([np.interp(stamps, t, data[k]) for k in ("fx", "fy", "fz")], axis=1)
    flange = R.flange_positions(tip)
    reading = R.sensor_reading(force)
    ms = (1.7e9 + session_time_s + stamps) * 1e3
    rows = ["stamp_ms,x_mm,y_mm,z_mm,Fx,Fy,Fz"]
    rows += [f"{m:.3f},{p[0] * 1e3:.4f},{p[1] * 1e3:.4f},{p[2] * 1e3:.4f},{f[0]:.5f},{f[1]:.5f},{f[2]:.5f}"
             for m, p, f in zip(ms, flange, reading)]
    out.write_text("\n".join(rows) + "\n")


@pytest.mark.calibrate_e2e
def test_a_60_hz_robot_log_imports_and_calibrates(tmp_path: Path) -> None:
    subprocess.run([sys.executable, str(GENERATOR), "--effects", "sensor_bias", "--seed", "2",
                    "--out", str(tmp_path / "gen")], check=True, capture_output=True)
    meta = json.loads((tmp_path / "gen" / "dataset" / "dataset.json").read_text())
    truth = json.loads((tmp_path / "gen" / "truth.json").read_text())
    logs = []
    for k, entry in enumerate(meta["recordings"]):
        path = tmp_path / "robot" / f"trial_{k:02d}.csv"
        path.parent.mkdir(exist_ok=True)
        robot_csv(tmp_path / "gen" / "dataset" / entry["file"], entry["session_time_s"], path,
                  gap=k % 3 == 1, seed=k)
        logs.append(path)
    (tmp_path / "mapping.toml").write_text(MAPPING)
    result = import_logs(logs, tmp_path / "dataset", load_mapping(tmp_path / "mapping.toml"))
    seen = json.loads(_native.read_recordings(tmp_path / "dataset"))
    by_source = {}
    for entry in result.recordings:
        by_source.setdefault(Path(entry["source"]["file"]).stem, set()).add(entry["site"])
    expected = {f"trial_{k:02d}": {e["site"]} for k, e in enumerate(meta["recordings"])}
    assert by_source == expected
    assert all(55 < r["rate_hz"] < 65 for r in seen["recordings"])
    assert np.allclose(seen["torso_center_xy"], truth["nuisances"]["torso_center_xy"], atol=3e-3)
    run = subprocess.run([sys.executable, "-m", "echogym", "calibrate", str(tmp_path / "dataset"),
                          "--out", str(tmp_path / "cal"), "--quiet"], capture_output=True, text=True,
                         timeout=2400)
    assert run.returncode == 0, run.stderr[-3000:]
    report = json.loads((tmp_path / "cal" / "report.json").read_text())
    named = {e["name"]: e for e in report["effects"]}
    # The bias is found; at 60 Hz the baseline is weak and a spurious site effect may be
    # named beside it (docs/results/robotdata.md), so only the bias is asserted.
    assert "sensor_bias" in named, (named, report["rejected"])
    assert abs(named["sensor_bias"]["params"]["fz_n"] - truth["effects"]["sensor_bias"]["fz_n"]) < 0.15
