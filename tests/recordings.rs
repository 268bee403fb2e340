//! The recordings format `echogym-recordings/1`: a dataset written in the background
//! reads back equal, unknown keys survive, velocities are derived when absent, real robot
//! logs read (median rate 50–2000 Hz, jittered time stamps), a gap (an interval over
//! max(5 × median, 0.05 s)) cuts a file into segments read as their own recordings
//! `<file>#k` with the file's keys, unshifted time and velocities never derived across the
//! gap, segments under 10 samples are dropped unless all are, every bad input (missing
//! column, non-increasing or repeated time, NaN, wrong format version, listed-but-absent
//! file, rate out of range, too few samples) is an error naming the file (and row), and
//! an unfinished dataset leaves nothing behind.

use std::path::{Path, PathBuf};

use echogym::recordings::{Dataset, DatasetWriter, FORMAT, Recording, RecordingsError};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("echogym-rec-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn press(rate: f64, n: usize) -> Recording {
    let t: Vec<f64> = (0..n).map(|i| i as f64 / rate).collect();
    let p: Vec<[f64; 3]> = t.iter().map(|t| [0.0, 0.0, 0.9 - 0.01 * t]).collect();
    let f: Vec<[f64; 3]> = t.iter().map(|t| [0.0, 0.0, 15.0 * t]).collect();
    Recording {
        v: vec![[0.0, 0.0, -0.01]; n],
        t,
        p,
        f,
        torque: None,
        velocity_measured: true,
    }
}

#[test]
fn written_datasets_read_back_equal() {
    let dir = scratch("roundtrip");
    let target = dir.join("set");
    let mut writer = DatasetWriter::create(&target, "two presses", 0.905, [0.0, 0.01]).unwrap();
    writer.meta_mut().notes = Some("synthetic".into());
    writer
        .meta_mut()
        .extra
        .insert("operator".into(), serde_json::json!("kept"));
    writer.add("center_press.csv", "center", "press", press(500.0, 1000));
    writer.add(
        "upper_left_press.csv",
        "upper_left",
        "press",
        press(1000.0, 800),
    );
    writer.finish().unwrap();

    let dataset = Dataset::read(&target).unwrap();
    assert_eq!(dataset.meta.format, FORMAT);
    assert_eq!(dataset.meta.extra["operator"], "kept");
    assert_eq!(dataset.recordings.len(), 2);
    let back = &dataset.recordings[0];
    let original = press(500.0, 1000);
    assert_eq!(back.len(), 1000);
    assert!((back.rate_hz() - 500.0).abs() < 1e-6);
    for i in [0, 500, 999] {
        assert!((back.f[i][2] - original.f[i][2]).abs() < 1e-8);
        assert!((back.p[i][2] - original.p[i][2]).abs() < 1e-8);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn an_existing_folder_is_never_replaced() {
    let dir = scratch("keep");
    let target = dir.join("set");
    std::fs::create_dir_all(&target).unwrap();
    std::fs::write(target.join("precious.txt"), "mine").unwrap();
    let mut writer = DatasetWriter::create(&target, "", 0.9, [0.0, 0.0]).unwrap();
    writer.add("a.csv", "center", "press", press(500.0, 100));
    let written = writer.finish().unwrap();
    assert_eq!(written, dir.join("set-2"));
    assert_eq!(
        std::fs::read_to_string(target.join("precious.txt")).unwrap(),
        "mine"
    );
    assert_eq!(Dataset::read(&written).unwrap().recordings.len(), 1);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_failed_write_leaves_nothing_behind() {
    // The temporary folder vanishes under the writer (as a full disk fails a write):
    // finish reports the error and nothing half-written remains.
    let dir = scratch("failed");
    let target = dir.join("set");
    let mut writer = DatasetWriter::create(&target, "", 0.9, [0.0, 0.0]).unwrap();
    for entry in std::fs::read_dir(&dir).unwrap().flatten() {
        std::fs::remove_dir_all(entry.path()).unwrap();
    }
    writer.add("a.csv", "center", "press", press(500.0, 100));
    assert!(matches!(writer.finish(), Err(RecordingsError::Io { .. })));
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    std::fs::remove_dir_all(&dir).unwrap();
}

fn write_dataset(dir: &Path, csv: &str, format: &str, listed: &[&str]) {
    let recordings: Vec<_> = listed
        .iter()
        .map(|f| serde_json::json!({"file": f, "site": "center", "protocol": "press"}))
        .collect();
    let meta = serde_json::json!({"format": format, "nominal_surface_z": 0.905,
        "torso_center_xy": [0.0, 0.0], "recordings": recordings});
    std::fs::write(dir.join("dataset.json"), meta.to_string()).unwrap();
    std::fs::write(dir.join("a.csv"), csv).unwrap();
}

fn rows(n: usize, rate: f64) -> String {
    (0..n)
        .map(|i| format!("{},0,0,0.9,0,0,1\n", i as f64 / rate))
        .collect()
}

fn error_of(csv: &str, format: &str, listed: &[&str]) -> RecordingsError {
    // A folder per call: tests run in parallel and several of them call this.
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = scratch(&format!("bad-{call}"));
    write_dataset(&dir, csv, format, listed);
    let err = Dataset::read(&dir).unwrap_err();
    std::fs::remove_dir_all(&dir).unwrap();
    err
}

#[test]
fn bad_inputs_name_the_file_and_row() {
    let good = format!("t,px,py,pz,fx,fy,fz\n{}", rows(50, 200.0));
    let dir = scratch("derived");
    write_dataset(&dir, &good, FORMAT, &["a.csv"]);
    let dataset = Dataset::read(&dir).unwrap();
    assert_eq!(dataset.recordings[0].v.len(), 50, "velocities derived");
    std::fs::remove_dir_all(&dir).unwrap();

    let err = error_of(
        &format!("t,px,py,pz,fx,fy\n{}", rows(50, 200.0)),
        FORMAT,
        &["a.csv"],
    )
    .to_string();
    assert!(err.contains("a.csv") && err.contains("`fz`"), "{err}");

    let mut backwards = good.clone();
    backwards.push_str("0.1,0,0,0.9,0,0,1\n");
    let err = error_of(&backwards, FORMAT, &["a.csv"]).to_string();
    assert!(
        err.contains("a.csv, row 52") && err.contains("does not increase"),
        "{err}"
    );

    let nan = good.replacen("0.9,0,0,1\n", "NaN,0,0,1\n", 3);
    let err = error_of(&nan, FORMAT, &["a.csv"]).to_string();
    assert!(
        err.contains("row 2") && err.contains("`pz` is not finite"),
        "{err}"
    );

    let err = error_of(&good, "echogym-recordings/2", &["a.csv"]).to_string();
    assert!(
        err.contains("dataset.json") && err.contains("unknown format"),
        "{err}"
    );

    let err = error_of(&good, FORMAT, &["a.csv", "b.csv"]).to_string();
    assert!(err.contains("b.csv") && err.contains("absent"), "{err}");

    let mut repeated = good.clone();
    repeated.push_str("0.245,0,0,0.9,0,0,1\n");
    let err = error_of(&repeated, FORMAT, &["a.csv"]).to_string();
    assert!(
        err.contains("a.csv, row 52") && err.contains("does not increase"),
        "{err}"
    );

    let err = error_of(
        &format!("t,px,py,pz,fx,fy,fz\n{}", rows(50, 30.0)),
        FORMAT,
        &["a.csv"],
    )
    .to_string();
    assert!(err.contains("a.csv") && err.contains("30.0 Hz"), "{err}");

    let err = error_of(
        &format!("t,px,py,pz,fx,fy,fz\n{}", rows(3000, 2500.0)),
        FORMAT,
        &["a.csv"],
    )
    .to_string();
    assert!(err.contains("a.csv") && err.contains("2500.0 Hz"), "{err}");

    let err = error_of(
        &format!("t,px,py,pz,fx,fy,fz\n{}", rows(9, 200.0)),
        FORMAT,
        &["a.csv"],
    )
    .to_string();
    assert!(
        err.contains("a.csv") && err.contains("only 9 samples"),
        "{err}"
    );
}

/// `n` rows from `t0` at `rate`, each interval off by up to ±`jitter` of 1 / `rate`
/// (deterministic), moving down at 1 cm/s from `z0`.
fn log_rows(n: usize, t0: f64, rate: f64, jitter: f64, z0: f64) -> String {
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut t = t0;
    let mut out = String::new();
    for i in 0..n {
        if i > 0 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let u = (state >> 11) as f64 / (1u64 << 53) as f64;
            t += (1.0 + jitter * (2.0 * u - 1.0)) / rate;
        }
        let z = z0 - 0.01 * (t - t0);
        out.push_str(&format!("{t},0.01,0,{z},0,0,{}\n", 5.0 + t));
    }
    out
}

#[test]
fn jittered_60_hz_logs_read() {
    let dir = scratch("jitter");
    let csv = format!(
        "t,px,py,pz,fx,fy,fz\n{}",
        log_rows(240, 0.0, 60.0, 0.2, 0.9)
    );
    write_dataset(&dir, &csv, FORMAT, &["a.csv"]);
    let dataset = Dataset::read(&dir).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(dataset.recordings.len(), 1);
    let entry = &dataset.meta.recordings[0];
    assert_eq!(entry.file, "a.csv", "an unsplit file keeps its name");
    assert_eq!(entry.segment, None);
    let rec = &dataset.recordings[0];
    assert_eq!(rec.len(), 240);
    assert!((rec.rate_hz() - 60.0).abs() < 1.0, "{}", rec.rate_hz());
    for v in &rec.v {
        assert!((v[2] + 0.01).abs() < 1e-6, "vz {}", v[2]);
    }
}

#[test]
fn a_gap_splits_a_recording_into_segments() {
    let dir = scratch("gap");
    // x.csv: 1 s at 200 Hz, a 0.5 s hole, 1 s more 2 cm higher (a jump the velocity must
    // not see); y.csv: whole.
    let first = log_rows(200, 0.0, 200.0, 0.1, 0.9);
    let last_t: f64 = first
        .lines()
        .last()
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let resume = last_t + 0.5;
    let csv = format!(
        "t,px,py,pz,fx,fy,fz\n{first}{}",
        log_rows(200, resume, 200.0, 0.1, 0.92)
    );
    std::fs::write(dir.join("x.csv"), csv).unwrap();
    std::fs::write(
        dir.join("y.csv"),
        format!("t,px,py,pz,fx,fy,fz\n{}", rows(50, 200.0)),
    )
    .unwrap();
    let meta = serde_json::json!({"format": FORMAT, "nominal_surface_z": 0.905,
        "torso_center_xy": [0.0, 0.0], "recordings": [
            {"file": "x.csv", "site": "upper_left", "protocol": "chirp", "operator": "kept"},
            {"file": "y.csv", "site": "center", "protocol": "press"}]});
    std::fs::write(dir.join("dataset.json"), meta.to_string()).unwrap();

    let dataset = Dataset::read(&dir).unwrap();
    let files: Vec<&str> = dataset
        .meta
        .recordings
        .iter()
        .map(|e| e.file.as_str())
        .collect();
    assert_eq!(files, ["x.csv#1", "x.csv#2", "y.csv"]);
    assert_eq!(dataset.recordings.len(), 3);
    for (k, entry) in dataset.meta.recordings[..2].iter().enumerate() {
        assert_eq!(
            (entry.site.as_str(), entry.protocol.as_str()),
            ("upper_left", "chirp")
        );
        assert_eq!(entry.extra["operator"], "kept");
        let segment = entry.segment.as_ref().unwrap();
        assert_eq!(
            (segment.source.as_str(), segment.number, segment.of),
            ("x.csv", k + 1, 2)
        );
        let rec = &dataset.recordings[k];
        assert_eq!(rec.len(), 200);
        assert_eq!(segment.start_s, rec.t[0]);
        for v in &rec.v {
            assert!(
                (v[2] + 0.01).abs() < 1e-6,
                "vz {} in segment {}",
                v[2],
                k + 1
            );
        }
    }
    assert_eq!(dataset.recordings[0].t[0], 0.0);
    assert!(
        (dataset.recordings[1].t[0] - resume).abs() < 1e-9,
        "time not shifted"
    );
    assert_eq!(dataset.meta.recordings[2].segment, None);

    let json = serde_json::to_value(&dataset.meta).unwrap();
    assert!(
        json["recordings"]
            .as_array()
            .unwrap()
            .iter()
            .all(|e| e.get("segment").is_none()),
        "segment is not written: {json}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn short_segments_are_dropped_unless_all_are() {
    // 20 samples, a 0.1 s hole (over 0.05 s), 3 samples: the tail is dropped.
    let mut csv = format!("t,px,py,pz,fx,fy,fz\n{}", rows(20, 200.0));
    for t in [0.2, 0.205, 0.21] {
        csv.push_str(&format!("{t},0,0,0.9,0,0,1\n"));
    }
    let dir = scratch("short");
    write_dataset(&dir, &csv, FORMAT, &["a.csv"]);
    let dataset = Dataset::read(&dir).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(dataset.recordings.len(), 1);
    assert_eq!(dataset.recordings[0].len(), 20);
    let entry = &dataset.meta.recordings[0];
    assert_eq!(entry.file, "a.csv#1");
    assert_eq!(
        entry.segment.as_ref().map(|s| (s.number, s.of)),
        Some((1, 2))
    );

    // Three pieces of 8 samples, 1 s apart: nothing usable.
    let mut csv = String::from("t,px,py,pz,fx,fy,fz\n");
    for piece in 0..3 {
        for i in 0..8 {
            csv.push_str(&format!(
                "{},0,0,0.9,0,0,1\n",
                piece as f64 + i as f64 / 200.0
            ));
        }
    }
    let err = error_of(&csv, FORMAT, &["a.csv"]).to_string();
    assert!(
        err.contains("a.csv") && err.contains("all 3 segments") && err.contains("10 samples"),
        "{err}"
    );
}

#[test]
fn unfinished_datasets_leave_nothing_behind() {
    let dir = scratch("unfinished");
    let target = dir.join("set");
    let mut writer = DatasetWriter::create(&target, "", 0.9, [0.0, 0.0]).unwrap();
    writer.add("a.csv", "center", "press", press(500.0, 100));
    drop(writer);
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        0,
        "no target, no temporary folder"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
