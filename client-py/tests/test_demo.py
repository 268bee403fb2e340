"""The README's main job, `echogym demo`: the scripted hybrid force/motion sweep on 8
UltrasoundScan envs holds the contact force within ±1 N of 5 N for at least 80 % of the
in-contact time, completes the sweep, and writes its figures, video and summary. Its output into
a pipe is plain lines: no progress-bar carriage returns, no escape codes."""

import json
import subprocess
import sys

import numpy as np


def test_demo_sweep_holds_the_force_and_writes_figures(server, tmp_path):
    out = tmp_path / "demo"
    result = subprocess.run(
        [sys.executable, "-m", "echogym", "demo", "--num-envs", "8", "--horizon", "1500",
         "--camera-size", "32", "--out", str(out), "--server", server.name],
        capture_output=True, text=True, timeout=600,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["num_envs"] == 8
    assert summary["within_1n_share_of_contact"] >= 0.8
    assert summary["in_contact_share"] > 0.5
    assert sum(c >= 1.0 for c in summary["sweep_completion"]) >= 6
    for name in ("force.png", "frames.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # demo.mp4: env 0's sweep, 25 frames/s, 256 × 256, the scene moving.
    import imageio.v2 as imageio

    reader = imageio.get_reader(str(out / "demo.mp4"), format="FFMPEG")
    frames = np.stack([np.asarray(f) for f in reader])
    assert reader.get_meta_data()["fps"] == 25
    reader.close()
    assert frames.shape == (1500 // 20 + 1, 256, 256, 3), frames.shape
    assert np.abs(frames[0].astype(float) - frames[-1].astype(float)).mean() > 0.5
    assert "env-steps/s" in result.stdout
    for stream in (result.stdout, result.stderr):
        assert "\r" not in stream and "\x1b[" not in stream, repr(stream[:300])
