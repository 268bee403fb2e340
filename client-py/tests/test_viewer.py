"""The rerun viewer from real runs: `echogym view --save`, `render_mode="rerun"` and the
`RerunRecorder` wrapper step a real server, and the recordings are read back with rerun's
own reader (`rerun.chunk.RrdReader`): the scene's entities (arm capsules, probe, table,
torso mesh, contact), the time series (F/T, target force, reward terms) and the images."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import echogym
from echogym.apps import view

rr = pytest.importorskip("rerun")
from rerun.chunk import RrdReader  # noqa: E402

SCAN = "echogym/UltrasoundScan-v0"
_TIME_COLUMNS = {"rerun.controls.RowId", "log_time", "sim_time"}


def read_rrd(path) -> dict[str, dict]:
    """Per entity path: ``static`` (logged once), ``steps`` (the step timeline of its
    rows, in time order) and each component's values in the same order (``None`` in rows
    that did not log it)."""
    rows: dict[str, list[tuple[int, dict]]] = {}
    static: dict[str, bool] = {}
    for chunk in RrdReader(path).store().stream().to_chunks():
        batch = chunk.to_record_batch()
        path_rows = rows.setdefault(chunk.entity_path, [])
        static[chunk.entity_path] = static.get(chunk.entity_path, False) or chunk.is_static
        names = [n for n in batch.schema.names if n not in _TIME_COLUMNS and n != "step"]
        steps = batch.column("step").to_pylist() if "step" in batch.schema.names else \
            [-1] * batch.num_rows
        columns = {n: batch.column(n).to_pylist() for n in names}
        for j, step in enumerate(steps):
            path_rows.append((step, {n: columns[n][j] for n in names}))
    entities: dict[str, dict] = {}
    for path, entries in rows.items():
        entries.sort(key=lambda r: r[0])
        entity: dict = {"static": static[path], "steps": [s for s, _ in entries if s >= 0]}
        for name in {n for _, r in entries for n in r}:
            entity[name] = [r.get(name) for _, r in entries]
        entities[path] = entity
    return entities


def series(e: dict, path: str) -> dict[str, np.ndarray]:
    """A time-series entity's lines by name (values in row order)."""
    names = next(n for n in e[path]["SeriesLines:names"] if n is not None)
    rows = np.array([r for r in e[path]["Scalars:scalars"] if r is not None])
    assert rows.shape[1] == len(names)
    return {name: rows[:, k] for k, name in enumerate(names)}


def test_view_saves_the_scene_and_time_series_of_every_env(server, tmp_path):
    path = tmp_path / "scan.rrd"
    code = view.main([SCAN, "--save", str(path), "--steps", "300", "--num-envs", "2",
                      "--every", "25", "--server", server.name])
    assert code == 0
    e = read_rrd(path)
    logged = list(range(0, 301, 25))
    for i in (0, 1):
        world = f"/world/env_{i}"
        # The arm's links as capsules (shapes once, poses every logged step).
        links = [p for p in e if p.startswith(f"{world}/arm/link") and "Capsules3D:radii" in e[p]]
        assert len(links) >= 4, sorted(e)
        for link in links:
            assert e[link]["static"] or e[link]["steps"] == logged
        poses = [p for p in e if p.startswith(f"{world}/arm/link") and "Transform3D:translation" in e[p]]
        assert all(e[p]["steps"] == logged for p in poses) and len(poses) >= len(links)
        assert "Boxes3D:half_sizes" in e[f"{world}/probe/0"]
        assert "Boxes3D:half_sizes" in e[f"{world}/table/0"]
        # The torso deforms: its mesh is logged every logged step and moves.
        torso = e[f"{world}/torso"]
        assert torso["steps"] == logged
        first, last = (np.array(torso["Mesh3D:vertex_positions"][k]) for k in (0, -1))
        assert first.shape == last.shape and first.shape[1] == 3 and len(first) > 500
        assert np.abs(first - last).max() > 1e-4
        # The topology once (the torso keeps its shape within the episode), vertices always.
        triangles = [t for t in torso["Mesh3D:triangle_indices"] if t is not None]
        assert len(triangles) == 1 and len(triangles[0]) > 1000
        assert np.array(triangles[0]).max() == len(first) - 1
        assert len(torso["Mesh3D:vertex_colors"][0]) == len(first)
        # Time series: F/T, the contact force against its 5 N target, reward terms.
        assert e[f"/env_{i}/ft"]["steps"] == logged
        assert list(series(e, f"/env_{i}/ft")) == ["fx", "fy", "fz", "tx", "ty", "tz"]
        force = series(e, f"/env_{i}/force")
        assert np.all(force["target"] == 5.0)
        assert force["axial"].max() > 2.0, force["axial"]  # the sweep presses the skin
        reward = series(e, f"/env_{i}/reward")
        assert set(reward) == {"total", "position", "orientation", "speed", "force",
                               "force_derivative"}
        assert e[f"/env_{i}/reward"]["steps"] == logged[1:]  # none at the reset
        assert "progress" in series(e, f"/env_{i}/info")
        # The contact point and the force arrow while pressing.
        arrows = e[f"{world}/contact/force"]["Arrows3D:vectors"]
        assert any(len(a) == 1 and a[0][2] > 0.0 for a in arrows)
        # Images: the cameras and the B-mode image.
        for image in ("cameras/front/rgb", "cameras/probe/depth", "ultrasound"):
            assert len(e[f"/env_{i}/{image}"]["steps"]) == len(logged), image


def test_render_mode_rerun_logs_a_single_env_and_hides_the_scene_fields(server, tmp_path):
    path = tmp_path / "push.rrd"
    recording = rr.RecordingStream("echogym-test")
    recording.save(path)
    with recording:
        env = gym.make("echogym/PushCube-v0", render_mode="rerun")
        assert "scene_colliders" not in env.observation_space.spaces
        env.reset(seed=1)
        for _ in range(10):
            env.step(env.action_space.sample())
        env.close()
    recording.disconnect()  # flushes and writes the file's footer
    e = read_rrd(path)
    assert e["/world/env_0/object/0"]["static"] or "Boxes3D:half_sizes" in e["/world/env_0/object/0"]
    assert len(series(e, "/env_0/reward")["total"]) == 10
    assert "/world/env_0/torso" not in e  # PushCube has no torso
    assert server.status()["leases"] == []


def test_rerun_recorder_needs_the_scene_state(server, tmp_path):
    with pytest.raises(ValueError, match="scene_state=True"):
        from echogym.rerun_recorder import RerunRecorder

        env = gym.make(SCAN)
        try:
            RerunRecorder(env)
        finally:
            env.close()
    from echogym.rerun_recorder import RerunRecorder

    path = tmp_path / "wrapped.rrd"
    recording = rr.RecordingStream("echogym-test")
    recording.save(path)
    env = RerunRecorder(gym.make(SCAN, scene_state=True), recording=recording, every=5)
    obs, _ = env.reset(seed=0)
    assert obs["scene_colliders"].shape[1] == 15  # asked for, so observed
    for _ in range(20):
        env.step(np.zeros(env.action_space.shape, np.float32))
    env.close()
    recording.disconnect()
    e = read_rrd(path)
    assert e["/world/env_0/torso"]["steps"] == [0, 5, 10, 15, 20]


def test_view_refuses_an_env_without_a_scene(server, tmp_path, capsys):
    code = view.main(["echogym/Null-v0", "--save", str(tmp_path / "null.rrd"), "--steps", "2",
                      "--server", server.name])
    assert code == 2
    assert "scene_state" in capsys.readouterr().err
    with pytest.raises(ValueError, match="render_mode 'rerun'"):
        echogym.EchoVectorEnv("echogym/Null-v0", 1, render_mode="rerun")
