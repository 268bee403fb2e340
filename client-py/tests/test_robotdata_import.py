"""`echogym import` end to end on logs written by the real format libraries: ROS 2 bags
in both storages (rosbags' Writer), a bare MCAP (the `mcap` package's ROS 2 writer), a
JointState log through the UR5e's URDF, and CSVs; the output is read back by the
calibration tool's own Rust reader (`echogym._native.read_recordings`). Bad input is
refused with a typed error naming the topic or column and time, and nothing is written."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import robot_logs as R
from echogym import _native
from echogym.robotdata import (
    ImportOptions,
    MappingError,
    MissingColumnError,
    MissingTopicError,
    NoPoseInReachError,
    NonFiniteError,
    NonMonotonicTimeError,
    UnknownMessageTypeError,
    import_logs,
    load_mapping,
)
from echogym.robotdata import gravity
from echogym.robotdata.rotations import matrix_from_rpy

REPO = Path(__file__).resolve().parents[2]
UR5E_URDF = REPO / "server" / "assets" / "robots" / "ur5e.urdf"
SITES = ["center", "upper_left", "lower_right", "upper_right", "center"]
BAG_TOPICS = dict(wrench_topic="/ft_sensor/wrench", pose_topic="/tcp_pose",
                  tool_offset=list(R.TOOL_OFFSET))


def read_back(out: Path) -> dict:
    """The dataset as the calibration tool's reader sees it."""
    return json.loads(_native.read_recordings(out))


def imported_csv(out: Path, file: str) -> np.ndarray:
    return np.genfromtxt(out / file, delimiter=",", names=True)


def check_against_truth(out: Path, session: R.Session, meta: dict, tol_n: float) -> None:
    """Sites, surface, centre and the force along the tip path match the ground truth."""
    seen = read_back(out)
    assert [r["site"] for r in seen["recordings"]] == SITES
    assert all(r["protocol"] == "press" for r in seen["recordings"])
    assert abs(seen["nominal_surface_z"] - R.SURFACE_Z) < 1e-3  # onset at the 0.5 N threshold
    assert np.allclose(seen["torso_center_xy"], R.TORSO_CENTER, atol=2e-3)
    for entry in meta["recordings"]:
        data = imported_csv(out, entry["file"])
        t = data["t"] + entry["source"]["t_start"]
        truth_z = np.interp(t, session.t, session.tip[:, 2])
        truth_f = np.interp(t, session.t, session.force[:, 2])
        assert np.abs(data["pz"] - truth_z).max() < 2e-4, "tip height (flange + tool offset)"
        assert np.sqrt(np.mean((data["fz"] - truth_f) ** 2)) < tol_n, entry["file"]


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_ros2_bag_imports_in_either_storage(tmp_path: Path, storage: str) -> None:
    session = R.session(SITES)
    R.write_ros2_bag(tmp_path / "bag", session, storage)
    result = import_logs(tmp_path / "bag", tmp_path / "out", **BAG_TOPICS)
    check_against_truth(tmp_path / "out", session, result.meta, tol_n=0.06)
    source = result.meta["provenance"]["sources"][0]
    assert source["wrench"] == {"topic": "/ft_sensor/wrench", "type": "geometry_msgs/msg/WrenchStamped",
                                "frame_id": ["tool0"], "messages": source["wrench"]["messages"]}
    assert source["gravity"]["method"] == "tare"  # the probe never turned
    assert abs(source["gravity"]["tare_force_tool_n"][2] - R.PROBE_MASS * R.G) < 1e-6
    assert [e["source"]["cut"] for e in result.recordings][1:] == ["site changed in free air"] * 4
    times = [e["session_time_s"] for e in result.recordings]
    assert times[0] == 0 and np.all(np.diff(times) > 5)


def test_tf_pose_and_a_given_mass_keep_the_sensor_bias(tmp_path: Path) -> None:
    session = R.session(SITES[:3])
    R.write_ros2_bag(tmp_path / "bag", session, "mcap", pose_kind="tf", bias=-0.7)
    result = import_logs(tmp_path / "bag", tmp_path / "out", wrench_topic="/ft_sensor/wrench",
                         pose_topic="/tf", tf_parent="base", tf_child="tool0",
                         tool_offset=list(R.TOOL_OFFSET), probe_mass=R.PROBE_MASS)
    first = imported_csv(tmp_path / "out", result.recordings[0]["file"])
    # Free air at the start: the weight is gone, the bias (−0.7 N along the tool's z,
    # which points down) is left for the calibration to name: +0.7 N in world z.
    assert abs(np.median(first["fz"][:100]) - 0.7) < 1e-6
    with pytest.raises(MappingError, match="tf_parent and tf_child"):
        import_logs(tmp_path / "bag", tmp_path / "out2", wrench_topic="/ft_sensor/wrench",
                    pose_topic="/tf")
    assert not (tmp_path / "out2").exists()


def test_topics_stamped_on_different_clocks_meet_on_the_receive_clock(tmp_path: Path) -> None:
    session = R.session(SITES)
    # The pose is stamped by a controller whose clock runs 37.5 s ahead of the sensor's PC.
    R.write_ros2_bag(tmp_path / "bag", session, "sqlite3", pose_clock_offset=37.5)
    result = import_logs(tmp_path / "bag", tmp_path / "out", **BAG_TOPICS)
    clock = result.meta["provenance"]["sources"][0]["clock"]
    assert clock["used"] == "header shifted to receive clock"
    assert abs(clock["shift_s"]["pose"] - (0.002 - 37.5)) < 1e-6
    check_against_truth(tmp_path / "out", session, result.meta, tol_n=0.06)
    with pytest.raises(NoPoseInReachError):
        import_logs(tmp_path / "bag", tmp_path / "out2", clock="header", **BAG_TOPICS)


def test_sites_by_cluster_or_by_a_site_map(tmp_path: Path) -> None:
    session = R.session(SITES)
    R.write_ros2_bag(tmp_path / "bag", session, "mcap")
    result = import_logs(tmp_path / "bag", tmp_path / "clusters", sites="cluster", **BAG_TOPICS)
    assert [e["site"] for e in result.recordings] == ["site_1", "site_2", "site_3", "site_4", "site_1"]
    site_map = {"navel": [0.0, 0.0], "liver": [-0.06, 0.08], "spleen": [0.06, 0.08],
                "bladder": [0.0, -0.1]}
    result = import_logs(tmp_path / "bag", tmp_path / "named", sites=site_map,
                         torso_center=list(R.TORSO_CENTER), **BAG_TOPICS)
    assert [e["site"] for e in result.recordings] == ["navel", "liver", "bladder", "spleen", "navel"]
    assert result.meta["provenance"]["estimated"]["torso_center_xy"] == "given"
    with pytest.raises(MappingError, match="tool_ofset"):
        import_logs(tmp_path / "bag", tmp_path / "x", tool_ofset=[0, 0, 0.1], **BAG_TOPICS)


def test_a_bare_mcap_from_the_mcap_writer_imports(tmp_path: Path) -> None:
    session = R.session(SITES)
    R.write_bare_mcap(tmp_path / "log.mcap", session)
    result = import_logs(tmp_path / "log.mcap", tmp_path / "out", wrench_topic="/wrench",
                         pose_topic="/flange_pose", tool_offset=list(R.TOOL_OFFSET))
    # 1 kHz wrench: within the format's range, kept on its own stamps.
    assert result.meta["provenance"]["sources"][0]["alignment"]["time_base"] == "wrench stamps"
    check_against_truth(tmp_path / "out", session, result.meta, tol_n=0.06)


def test_a_fast_wrench_is_resampled_and_rates_can_be_set(tmp_path: Path) -> None:
    session = R.session(SITES[:2])
    R.write_ros2_bag(tmp_path / "bag", session, "sqlite3", wrench_rate=4000.0, pose_rate=60.0)
    result = import_logs(tmp_path / "bag", tmp_path / "out", **BAG_TOPICS)
    assert result.meta["provenance"]["sources"][0]["alignment"]["time_base"] == "uniform 1000 Hz"
    rates = [r["rate_hz"] for r in read_back(tmp_path / "out")["recordings"]]
    assert np.allclose(rates, 1000.0, rtol=1e-6)
    result = import_logs(tmp_path / "bag", tmp_path / "out200", rate_hz=200.0, **BAG_TOPICS)
    assert np.allclose([r["rate_hz"] for r in read_back(tmp_path / "out200")["recordings"]], 200.0)


def test_joint_states_through_the_ur5e_urdf(tmp_path: Path) -> None:
    """Joint states at the UR5e's home put tool0 at the published (0.4919, 0.1333, 0.4879) m,
    z axis down: a press read −5 N along the tool's z is +5 N up in the world."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
             "wrist_2_joint", "wrist_3_joint"]
    home = [0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0]
    Header, Time = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    V = ts.types["geometry_msgs/msg/Vector3"]
    with Writer(tmp_path / "bag", version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        js = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=ts)
        ft = w.add_connection("/wrench", "geometry_msgs/msg/WrenchStamped", typestore=ts)
        for i in range(1500):  # 3 s at 500 Hz
            t = 100.0 + i * 0.002
            stamp = Time(sec=int(t), nanosec=int(round((t - int(t)) * 1e9)))
            # The joint state lists its joints in another order than the URDF chain.
            msg = ts.types["sensor_msgs/msg/JointState"](
                header=Header(stamp=stamp, frame_id=""), name=names[::-1],
                position=np.array(home[::-1]), velocity=np.zeros(6), effort=np.zeros(6))
            w.write(js, int(t * 1e9), ts.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
            pressing = 1.0 <= t - 100.0 < 2.0
            wrench = ts.types["geometry_msgs/msg/WrenchStamped"](
                header=Header(stamp=stamp, frame_id="tool0"),
                wrench=ts.types["geometry_msgs/msg/Wrench"](
                    force=V(x=0.0, y=0.0, z=-5.0 if pressing else 0.0), torque=V(x=0.0, y=0.0, z=0.0)))
            w.write(ft, int(t * 1e9), ts.serialize_cdr(wrench, "geometry_msgs/msg/WrenchStamped"))
    result = import_logs(tmp_path / "bag", tmp_path / "out", wrench_topic="/wrench",
                         pose_topic="/joint_states", urdf=str(UR5E_URDF), probe_mass="none")
    data = imported_csv(tmp_path / "out", result.recordings[0]["file"])
    assert np.allclose([data["px"].mean(), data["py"].mean(), data["pz"].mean()],
                       [0.4919, 0.1333, 0.4879], atol=1e-4)
    assert abs(data["fz"].max() - 5.0) < 1e-9 and abs(data["fx"]).max() < 1e-9
    with pytest.raises(MappingError, match="URDF"):
        import_logs(tmp_path / "bag", tmp_path / "out2", wrench_topic="/wrench",
                    pose_topic="/joint_states")


def write_robot_csv(path: Path, session: R.Session, rate=60.0, gaps=((20.0, 0.6),), seed=4):
    """A robot's own CSV: 60 Hz with ±30 % jitter, dropped stretches (``(at s, length s)``),
    millimetres, milliseconds, the flange pose, the sensor-frame wrench with the weight."""
    rng = np.random.default_rng(seed)
    stamps = R.jittered_stamps(session.t[0], session.t[-1], rate, 0.3, rng)
    for at, length in gaps:
        rel = stamps - session.t[0]
        stamps = stamps[(rel < at) | (rel > at + length)]
    flange = R.flange_positions(R.sample(session, stamps, session.tip))
    reading = R.sensor_reading(R.sample(session, stamps, session.force))
    reading += rng.normal(0, 0.03, reading.shape)  # sensor noise
    ms = (stamps - session.t[0]) * 1e3 + 5e5  # the logger's own millisecond clock
    rows = ["stamp_ms,x_mm,y_mm,z_mm,Fx,Fy,Fz"]
    rows += [f"{m:.3f},{p[0] * 1e3:.4f},{p[1] * 1e3:.4f},{p[2] * 1e3:.4f},{f[0]:.4f},{f[1]:.4f},{f[2]:.4f}"
             for m, p, f in zip(ms, flange, reading)]
    path.write_text("\n".join(rows) + "\n")


CSV_MAPPING = """
[csv]
time = "stamp_ms"
time_unit = "ms"
position = ["x_mm", "y_mm", "z_mm"]
position_unit = "mm"
force = ["Fx", "Fy", "Fz"]
orientation_rpy = [3.141592653589793, 0.0, 0.0]   # the probe upright, tool z down

[probe]
tool_offset = [0.0, 0.0, 0.11]
"""


def test_a_60_hz_csv_with_jitter_gaps_and_millimetres(tmp_path: Path) -> None:
    session = R.session(SITES)
    write_robot_csv(tmp_path / "robot.csv", session)
    (tmp_path / "mapping.toml").write_text(CSV_MAPPING)
    options = load_mapping(tmp_path / "mapping.toml")
    result = import_logs(tmp_path / "robot.csv", tmp_path / "out", options)
    cuts = [e["source"]["cut"] for e in result.recordings]
    assert sum("between gaps" in c for c in cuts) == 2, cuts  # the 0.6 s hole splits a stretch
    seen = read_back(tmp_path / "out")
    assert [r["site"] for r in seen["recordings"]] == SITES
    assert all(55 < r["rate_hz"] < 65 for r in seen["recordings"])
    assert abs(seen["nominal_surface_z"] - R.SURFACE_Z) < 1.5e-3


def test_the_command_line_with_a_mapping_file(tmp_path: Path) -> None:
    session = R.session(SITES[:3])
    write_robot_csv(tmp_path / "robot.csv", session, gaps=())
    (tmp_path / "mapping.toml").write_text(CSV_MAPPING)
    run = subprocess.run([sys.executable, "-m", "echogym", "import", str(tmp_path / "robot.csv"),
                          "--mapping", str(tmp_path / "mapping.toml"), "--out", str(tmp_path / "out"),
                          "--probe-mass", "0.25"], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "gravity given, 0.250 kg" in run.stdout and "upper_left, press" in run.stdout
    assert [r["site"] for r in read_back(tmp_path / "out")["recordings"]] == SITES[:3]
    bad = subprocess.run([sys.executable, "-m", "echogym", "import", str(tmp_path / "robot.csv"),
                          "--out", str(tmp_path / "out2")], capture_output=True, text=True, timeout=120)
    assert bad.returncode == 1 and "robot.csv, t: no such column (csv.time)" in bad.stderr
    assert not (tmp_path / "out2").exists()


def test_bad_input_is_refused_naming_topic_or_column_and_time(tmp_path: Path) -> None:
    session = R.session(SITES[:2])
    R.write_ros2_bag(tmp_path / "bag", session, "mcap")
    out = tmp_path / "out"
    with pytest.raises(MissingTopicError, match=r"/ft_sensor/wrnch.*topics: /ft_sensor/wrench"):
        import_logs(tmp_path / "bag", out, wrench_topic="/ft_sensor/wrnch", pose_topic="/tcp_pose")
    with pytest.raises(UnknownMessageTypeError, match="PoseStamped cannot be the wrench"):
        import_logs(tmp_path / "bag", out, wrench_topic="/tcp_pose", pose_topic="/tcp_pose")
    with pytest.raises(MappingError, match="wrench_sign.*force rises when the probe goes up"):
        import_logs(tmp_path / "bag", out, wrench_sign=-1.0, probe_mass=R.PROBE_MASS, **BAG_TOPICS)
    with pytest.raises(NoPoseInReachError, match="/ft_sensor/wrench.*no wrench sample has a pose"):
        import_logs(tmp_path / "bag", out, pose_time_offset_s=3600.0, **BAG_TOPICS)

    write_robot_csv(tmp_path / "robot.csv", session, gaps=())
    options = load_mapping(_mapping(tmp_path))
    lines = (tmp_path / "robot.csv").read_text().splitlines()
    lines[200] = lines[198]  # a repeated stamp
    (tmp_path / "repeat.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(NonMonotonicTimeError, match="stamp_ms at t = .*does not increase") as err:
        import_logs(tmp_path / "repeat.csv", out, options)
    assert err.value.where == "stamp_ms" and err.value.time_s is not None
    lines = (tmp_path / "robot.csv").read_text().splitlines()
    for k in range(300, 310):
        cells = lines[k].split(",")
        cells[6] = "nan"
        lines[k] = ",".join(cells)
    (tmp_path / "nan.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(NonFiniteError, match="Fz.*row 301: nan"):
        import_logs(tmp_path / "nan.csv", out, options)
    with pytest.raises(MissingColumnError, match="force_z"):
        options.csv.force = ["Fx", "Fy", "force_z"]
        import_logs(tmp_path / "robot.csv", out, options)
    (tmp_path / "bad.toml").write_text("[probe]\nmas = 0.2\n")
    with pytest.raises(MappingError, match="probe.mas"):
        load_mapping(tmp_path / "bad.toml")
    assert not out.exists() and not list(tmp_path.glob(".out.partial-*"))


def _mapping(tmp_path: Path) -> Path:
    path = tmp_path / "mapping.toml"
    path.write_text(CSV_MAPPING)
    return path


def test_gravity_separates_weight_from_bias_when_the_probe_turns() -> None:
    rng = np.random.default_rng(0)
    rot = np.array([matrix_from_rpy([np.pi + a, b, c]) for a, b, c in
                    rng.uniform(-0.4, 0.4, (400, 3))])
    mass, bias, com = 0.31, np.array([0.2, -0.1, 0.5]), np.array([0.0, 0.01, 0.05])
    g_tool = np.einsum("nji,j->ni", rot, gravity.GRAVITY_WORLD)
    f = mass * g_tool + bias + rng.normal(0, 0.01, (400, 3))
    tq = np.cross(mass * com, g_tool)
    t = np.arange(400) * 0.01
    model = gravity.estimate("test", "wrench", t, f, tq, rot, np.ones(400, bool))
    assert model.method == "estimated"
    assert abs(model.mass_kg - mass) < 2e-3
    assert np.allclose(model.notes["sensor_bias_tool_n"], bias, atol=5e-3)
    assert np.allclose(model.mass_moment / model.mass_kg, com, atol=1e-3)
    world = np.einsum("nij,nj->ni", rot, f)
    compensated, _ = gravity.compensate(world, None, rot, model)
    # What is left is the bias, turning with the tool.
    assert np.allclose(compensated, np.einsum("nij,j->ni", rot, bias), atol=0.05)
    with pytest.raises(gravity.GravityEstimateError, match="free air"):
        gravity.estimate("test", "wrench", t, f, tq, rot, np.arange(400) < 10)


def test_options_refuse_values_out_of_their_domain() -> None:
    with pytest.raises(MappingError, match="rate_hz"):
        ImportOptions(rate_hz=20.0).check()
    with pytest.raises(MappingError, match="csv.position_unit"):
        options = ImportOptions()
        options.csv.position_unit = "inch"
        options.check()
