//! The recordings format `echogym-recordings/1`: a dataset written in the background
//! reads back equal, unknown keys survive, velocities are derived when absent, every bad
//! input (missing column, non-increasing time, NaN, wrong format version, listed-but-absent
//! file, non-constant or out-of-range rate) is an error naming the file and row, and an
//! unfinished dataset leaves nothing behind.

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
    let dir = scratch("bad");
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

    let err = error_of(
        &format!("t,px,py,pz,fx,fy,fz\n{}", rows(50, 50.0)),
        FORMAT,
        &["a.csv"],
    )
    .to_string();
    assert!(err.contains("50.0 Hz"), "{err}");

    let mut gap = format!("t,px,py,pz,fx,fy,fz\n{}", rows(20, 200.0));
    gap.push_str("0.2,0,0,0.9,0,0,1\n");
    let err = error_of(&gap, FORMAT, &["a.csv"]).to_string();
    assert!(err.contains("row 22") && err.contains("constant"), "{err}");
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
