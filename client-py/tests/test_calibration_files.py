"""Reading `echogym calibrate`'s output files from Python (`echogym.calibration`)."""

from __future__ import annotations

from pathlib import Path

from echogym.calibration import load_replay


def test_the_replay_of_a_segment_cut_at_a_gap_loads(tmp_path: Path) -> None:
    # The report lists segment 2 of `press.csv` as `press.csv#2`; the Rust report writes
    # its replay to `replay/press#2.csv` (server/src/calibrate/report.rs).
    (tmp_path / "replay").mkdir()
    (tmp_path / "replay" / "press#2.csv").write_text("t,fz_measured\n0.5,1.25\n")
    (tmp_path / "replay" / "press.csv").write_text("t,fz_measured\n0.0,0.5\n")
    assert load_replay(tmp_path, "press.csv#2") == {"t": [0.5], "fz_measured": [1.25]}
    assert load_replay(tmp_path, "press.csv") == {"t": [0.0], "fz_measured": [0.5]}
