//! Tests every physics env through the registry: seeded determinism, config errors,
//! randomization ranges, the scripted press and its recording, breathing under a held
//! probe.

use echogym_protocol::EnvSpec;

use crate::envs::env::{Env, EnvOutput};
use crate::envs::registry::EnvRegistry;

const IDS: [&str; 3] = [
    "echogym/UltrasoundScan-v0",
    "echogym/PushCube-v0",
    "echogym/CalibrationPress-v0",
];

fn map(json: serde_json::Value) -> serde_json::Map<String, serde_json::Value> {
    json.as_object().expect("object").clone()
}

fn make(id: &str, config: serde_json::Value) -> (EnvSpec, Box<dyn Env>) {
    let registry = EnvRegistry::default();
    let factory = registry.get(id).unwrap();
    let spec = factory.spec(&map(config)).unwrap();
    let env = factory.make(&spec).unwrap();
    (spec, env)
}

/// Run `steps` steps of a fixed action sequence; returns every record and info row.
fn rollout(
    id: &str,
    config: serde_json::Value,
    seed: u64,
    steps: usize,
) -> Vec<(Vec<u8>, Vec<f32>)> {
    let (spec, mut env) = make(id, config);
    let mut record = vec![0u8; spec.obs_record_bytes];
    let mut info = vec![0.0f32; spec.info_keys.len()];
    let mut out = EnvOutput::new(&spec.observation, &mut record, &mut info);
    env.reset(Some(seed), &mut out);
    let mut trace = vec![(record.clone(), info.clone())];
    for k in 0..steps {
        let action: Vec<f32> = (0..spec.action.size)
            .map(|i| ((k * 7 + i * 3) % 11) as f32 / 11.0 - 0.5)
            .collect();
        let mut out = EnvOutput::new(&spec.observation, &mut record, &mut info);
        env.step(&action, &mut out);
        trace.push((record.clone(), info.clone()));
    }
    trace
}

#[test]
fn every_env_is_deterministic_under_a_seed() {
    for id in IDS {
        let a = rollout(id, serde_json::json!({}), 11, 20);
        let b = rollout(id, serde_json::json!({}), 11, 20);
        assert!(a == b, "{id}: same seed, different rollout");
        let c = rollout(id, serde_json::json!({}), 12, 20);
        assert!(a != c, "{id}: different seeds, same rollout");
    }
}

#[test]
fn cameras_deliver_images_in_the_record() {
    let config = serde_json::json!({
        "cameras": [{"name": "front", "width": 32, "height": 24}, {"name": "probe", "rgb": false}],
    });
    let trace = rollout("echogym/UltrasoundScan-v0", config.clone(), 1, 2);
    let (spec, _) = make("echogym/UltrasoundScan-v0", config);
    let rgb = spec.field("front_rgb").unwrap();
    assert_eq!(rgb.shape, vec![24, 32, 3]);
    let depth = spec.field("front_depth").unwrap();
    for (record, _) in [&trace[0], trace.last().unwrap()] {
        let pixels = &record[rgb.offset..rgb.offset + rgb.byte_len()];
        assert!(pixels.iter().any(|&p| p != pixels[0]), "a flat image");
    }
    let (record, _) = trace.last().unwrap();
    let d: &[f32] = bytemuck::cast_slice(&record[depth.offset..depth.offset + depth.byte_len()]);
    assert!(d.iter().all(|v| *v > 0.0 && *v <= 10.0));
    let probe = spec.field("probe_depth").unwrap();
    let d: &[f32] = bytemuck::cast_slice(&record[probe.offset..probe.offset + probe.byte_len()]);
    // The probe camera looks at the skin a few centimetres away.
    let centre = d[32 * 64 + 32];
    assert!(centre > 0.05 && centre < 0.3, "probe camera depth {centre}");
    assert!(spec.field("probe_rgb").is_none());
}

#[test]
fn bad_configs_name_the_key() {
    let registry = EnvRegistry::default();
    let cases = [
        (serde_json::json!({"horizn": 10}), "horizn"),
        (
            serde_json::json!({"task": {"target_forse": 1.0}}),
            "target_forse",
        ),
        (
            serde_json::json!({"task": {"target_force": -1.0}}),
            "task.target_force",
        ),
        (
            serde_json::json!({"randomization": {"torso_stiffness": [1600.0, 1300.0]}}),
            "randomization.torso_stiffness",
        ),
        (
            serde_json::json!({"cameras": [{"name": "nowhere"}]}),
            "cameras",
        ),
        (
            serde_json::json!({"controller": {"control_freq": 5000.0}}),
            "controller",
        ),
        (
            serde_json::json!({"torso": {"stiffness": -1.0}}),
            "stiffness",
        ),
        (
            serde_json::json!({"observations": ["joint_pos", "x_ray"]}),
            "x_ray",
        ),
        (serde_json::json!({"robot": "ur10"}), "ur10"),
        (
            serde_json::json!({"robot": {"urdf": "/nonexistent/arm.urdf"}}),
            "`robot`: cannot read URDF /nonexistent/arm.urdf",
        ),
        (
            serde_json::json!({"robot": {"urdf": "/a.urdf", "tool_ofset": [0, 0, 0]}}),
            "tool_ofset",
        ),
    ];
    let factory = registry.get("echogym/UltrasoundScan-v0").unwrap();
    for (config, key) in cases {
        let err = factory.spec(&map(config.clone())).unwrap_err().to_string();
        assert!(err.contains(key), "{config}: {err}");
    }
}

/// A user's URDF reaches the env from the config: the built-in UR5e's URDF given as a
/// file with its home pose rolls out bit for bit like `robot = "ur5e"`; a tool mount moves
/// the probe; a bad file or home is refused at creation, naming `robot`.
#[test]
fn urdf_arms_from_the_config_drive_the_envs() {
    use crate::sim::robot::RobotKind;
    let dir = std::env::temp_dir().join(format!("echogym-arena-urdf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("ur5e.urdf");
    std::fs::write(&path, RobotKind::Ur5e.urdf()).unwrap();
    std::fs::write(dir.join("broken.urdf"), "not xml").unwrap();
    let id = "echogym/UltrasoundScan-v0";
    let home = RobotKind::Ur5e.home();

    let builtin = rollout(id, serde_json::json!({"robot": "ur5e"}), 3, 10);
    let file = serde_json::json!({"robot": {"urdf": path, "home": home}});
    assert!(
        rollout(id, file, 3, 10) == builtin,
        "URDF file and built-in differ"
    );
    let mounted =
        serde_json::json!({"robot": {"urdf": path, "home": home, "tool_offset": [0.0, 0.0, 0.03]}});
    let (spec, _) = make(id, mounted.clone());
    assert_eq!(spec.action.size, 6);
    assert!(
        rollout(id, mounted, 3, 10) != builtin,
        "the tool mount changed nothing"
    );

    let registry = EnvRegistry::default();
    let factory = registry.get(id).unwrap();
    let refused = |robot: serde_json::Value| {
        factory
            .spec(&map(serde_json::json!({"robot": robot})))
            .unwrap_err()
            .to_string()
    };
    let broken = refused(serde_json::json!({"urdf": dir.join("broken.urdf")}));
    assert!(
        broken.contains("`robot`") && broken.contains("broken.urdf"),
        "{broken}"
    );
    let short = refused(serde_json::json!({"urdf": path, "home": [0.0, 0.0]}));
    assert!(
        short.contains("home has 2 values for the 6 joints"),
        "{short}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn randomization_stays_in_range_and_follows_the_seed() {
    use super::{ArenaEnv, TaskConfig};
    use crate::envs::ultrasound_scan::{UltrasoundScan, UltrasoundScanConfig};
    let config = UltrasoundScanConfig::arena_default();
    let draw = |seed: u64| {
        let mut env = ArenaEnv::<UltrasoundScan>::new(config.clone()).unwrap();
        let (spec, _) = make("echogym/UltrasoundScan-v0", serde_json::json!({}));
        let mut record = vec![0u8; spec.obs_record_bytes];
        let mut info = vec![0.0f32; spec.info_keys.len()];
        env.reset(
            Some(seed),
            &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
        );
        let torso = env.scene().torso().unwrap().params().clone();
        (torso, env.scene().params().probe.mass)
    };
    let mut seen_low = false;
    for seed in 0..12 {
        let (torso, mass) = draw(seed);
        assert!(
            (1300.0..=1600.0).contains(&torso.stiffness),
            "{}",
            torso.stiffness
        );
        assert!((17.0..=41.0).contains(&torso.damping), "{}", torso.damping);
        assert!(torso.center_xy[0].abs() <= 0.02 && torso.center_xy[1].abs() <= 0.02);
        assert!((0.18..=0.22).contains(&mass));
        seen_low |= torso.stiffness < 1450.0;
        assert_eq!(draw(seed), (torso, mass), "seed {seed} not reproducible");
    }
    assert!(seen_low, "draws never reached the lower half of the range");
}

#[test]
fn scripted_press_reaches_depth_and_records_it() {
    // Unit tests run without a daemon: the system temp folder is this process's root.
    crate::recordings::root::set_root(&std::env::temp_dir());
    let dir = std::env::temp_dir().join(format!("echogym-press-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let config = serde_json::json!({
        "task": {"site": "center", "hold_time": 0.3},
        "record": {"dir": dir},
    });
    let (spec, mut env) = make("echogym/CalibrationPress-v0", config);
    let mut record = vec![0u8; spec.obs_record_bytes];
    let mut info = vec![0.0f32; spec.info_keys.len()];
    env.reset(
        Some(0),
        &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
    );
    let mut deepest: f32 = 0.0;
    let mut strongest: f32 = 0.0;
    let mut steps = 0;
    loop {
        let t = env.step(
            &vec![0.0; spec.action.size],
            &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
        );
        steps += 1;
        deepest = deepest.max(info[1]);
        strongest = strongest.max(info[3]);
        if t.terminated || steps > 4000 {
            break;
        }
    }
    assert_eq!(info[5], 1.0, "protocol did not complete in {steps} steps");
    assert!((deepest - 0.015).abs() < 0.002, "deepest {deepest}");
    // ≈ 1.7 kN/m static stiffness at the centre × 15 mm.
    assert!(strongest > 15.0 && strongest < 45.0, "force {strongest}");
    drop(env);
    let datasets: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert_eq!(datasets.len(), 1);
    let path = datasets[0].as_ref().unwrap().path();
    let dataset = crate::recordings::Dataset::read(&path).unwrap();
    assert_eq!(dataset.recordings.len(), 1);
    assert_eq!(dataset.meta.recordings[0].site, "center");
    let rec = &dataset.recordings[0];
    let peak = rec.f.iter().map(|f| f[2]).fold(f64::MIN, f64::max);
    assert!(peak > 10.0, "recorded force peak {peak}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Force during the hold of a scripted press (position held) at the centre.
fn held_force(breathing: bool) -> Vec<f64> {
    let mut config = serde_json::json!({
        "task": {"site": "center", "hold_time": 12.0, "press_depth": 0.005},
        "horizon": 20000,
        "randomization": {"breathing_rate_bpm": [15.0, 15.0], "breathing_amplitude": [0.005, 0.005]},
    });
    if breathing {
        config["breathing"] = serde_json::json!({"rate_drift": 0.0});
    }
    let (spec, mut env) = make("echogym/CalibrationPress-v0", config);
    let mut record = vec![0u8; spec.obs_record_bytes];
    let mut info = vec![0.0f32; spec.info_keys.len()];
    env.reset(
        Some(0),
        &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
    );
    let mut force = Vec::new();
    for _ in 0..20000 {
        let t = env.step(
            &vec![0.0; spec.action.size],
            &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
        );
        // Phase 1 (hold), after a second of settling.
        if info[4] == 1.0 {
            force.push(f64::from(info[3]));
        }
        if t.terminated {
            break;
        }
    }
    force.split_off(500)
}

/// Amplitude of the component of `x` (sampled at 500 Hz) at `hz`.
fn amplitude_at(x: &[f64], hz: f64) -> f64 {
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    let (mut c, mut s) = (0.0, 0.0);
    for (k, v) in x.iter().enumerate() {
        let phase = std::f64::consts::TAU * hz * k as f64 / 500.0;
        c += (v - mean) * phase.cos();
        s += (v - mean) * phase.sin();
    }
    2.0 * c.hypot(s) / x.len() as f64
}

#[test]
fn breathing_makes_a_held_probe_feel_the_breathing_rate() {
    let force = held_force(true);
    assert!(force.len() > 4000, "hold too short: {}", force.len());
    let at_rate = amplitude_at(&force, 0.25);
    for other in [0.1, 0.4, 0.6] {
        assert!(
            at_rate > 3.0 * amplitude_at(&force, other),
            "0.25 Hz not dominant vs {other} Hz"
        );
    }
    // 5 mm of rise against ≈ 1.7 kN/m, partly absorbed by the held arm: newtons.
    assert!(at_rate > 1.0, "breathing force amplitude {at_rate} N");
    let still = held_force(false);
    assert!(
        amplitude_at(&still, 0.25) < 0.1 * at_rate,
        "force oscillates without breathing"
    );
}

/// Row (4 cm and deeper) of the brightest mean echo across the central lines.
fn brightest_deep_row(image: &[u8], lines: usize) -> usize {
    let row_mean = |r: usize| {
        (lines / 4..3 * lines / 4)
            .map(|l| f64::from(image[r * lines + l]))
            .sum::<f64>()
    };
    let rows = image.len() / lines;
    (rows / 3..rows)
        .max_by(|&a, &b| row_mean(a).total_cmp(&row_mean(b)))
        .unwrap()
}

#[test]
fn ultrasound_follows_contact_and_deformation_in_a_real_press() {
    let config = serde_json::json!({
        "task": {"site": "center", "hold_time": 0.2},
        "ultrasound": {"cameras_are_not_needed": null},
    });
    let registry = EnvRegistry::default();
    let factory = registry.get("echogym/CalibrationPress-v0").unwrap();
    let err = factory.spec(&map(config)).unwrap_err().to_string();
    assert!(err.contains("cameras_are_not_needed"), "{err}");

    let config = serde_json::json!({
        "task": {"site": "center", "hold_time": 0.2},
        "ultrasound": {},
    });
    let (spec, mut env) = make("echogym/CalibrationPress-v0", config);
    let field = spec.field("ultrasound").unwrap().clone();
    assert_eq!(field.shape, vec![128, 128]);
    let keys = &spec.info_keys;
    let key = |name: &str| keys.iter().position(|k| k == name).unwrap();
    let (coupled, quality, depth) = (key("us_coupled"), key("us_quality"), key("depth"));
    let mut record = vec![0u8; spec.obs_record_bytes];
    let mut info = vec![0.0f32; keys.len()];
    env.reset(
        Some(3),
        &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
    );
    // Probe above the skin: no signal at all.
    let image = |record: &[u8]| record[field.offset..field.offset + field.byte_len()].to_vec();
    assert!(image(&record).iter().all(|&v| v == 0));
    assert_eq!(info[coupled], 0.0);
    // Press: the image appears on contact, and deep echoes rise as the tissue compresses.
    let mut first_contact: Option<(f32, usize)> = None;
    let mut deepest = (0.0f32, 0usize);
    for _ in 0..4000 {
        let t = env.step(
            &vec![0.0; spec.action.size],
            &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
        );
        if info[coupled] > 0.95 && info[depth] > 0.001 {
            let row = brightest_deep_row(&image(&record), 128);
            first_contact.get_or_insert((info[depth], row));
            if info[depth] > deepest.0 {
                deepest = (info[depth], row);
            }
            assert!(info[quality] > 0.5, "coupled but quality {}", info[quality]);
        }
        if t.terminated {
            break;
        }
    }
    let (d0, r0) = first_contact.expect("the press never coupled the probe");
    let (d1, r1) = deepest;
    assert!(d1 - d0 > 0.01, "pressed only {d0} → {d1} m");
    // The vertebra's top (87 mm at rest) is imaged at ≈ 87·(1 + w/H) mm: ≈ 1 row up per
    // 1.1 mm pressed.
    assert!(
        r1 + 6 <= r0,
        "deep echo at row {r0} at {d0} m, row {r1} at {d1} m"
    );
}

fn f32_field<'a>(spec: &EnvSpec, record: &'a [u8], name: &str) -> &'a [f32] {
    let f = spec
        .field(name)
        .unwrap_or_else(|| panic!("no field {name}"));
    bytemuck::cast_slice(&record[f.offset..f.offset + f.byte_len()])
}

#[test]
fn scene_state_is_off_by_default_and_describes_the_scene_when_on() {
    let (spec, _) = make("echogym/UltrasoundScan-v0", serde_json::json!({}));
    assert!(spec.field("scene_colliders").is_none());
    let config = serde_json::json!({"scene_state": true, "robot": "ur5e"});
    let (spec, _) = make("echogym/UltrasoundScan-v0", config.clone());
    let colliders = spec.field("scene_colliders").unwrap().shape.clone();
    assert_eq!(colliders[1], crate::envs::arena::COLLIDER_COLUMNS);
    let trace = rollout("echogym/UltrasoundScan-v0", config, 3, 5);
    let (record, _) = trace.last().unwrap();
    let rows: Vec<&[f32]> = f32_field(&spec, record, "scene_colliders")
        .chunks_exact(15)
        .collect();
    // The table, the probe and at least four arm links (the torso is its own mesh).
    let parts: Vec<f32> = rows.iter().filter(|r| r[0] >= 0.0).map(|r| r[1]).collect();
    for part in [0.0, 2.0] {
        assert_eq!(
            parts.iter().filter(|&&p| p == part).count(),
            1,
            "part {part}"
        );
    }
    assert!(
        parts.iter().filter(|&&p| p >= 4.0).count() >= 4,
        "{parts:?}"
    );
    for row in rows.iter().filter(|r| r[0] >= 0.0) {
        let q = &row[11..15];
        let norm: f32 = q.iter().map(|v| v * v).sum();
        assert!((norm - 1.0).abs() < 1e-4, "quaternion {q:?}");
    }
    // The probe row sits where the probe observation says its tip is (half a probe back).
    let probe = rows.iter().find(|r| r[1] == 2.0).unwrap();
    let tip = f32_field(&spec, record, "probe_pose");
    let gap: f32 = (0..3)
        .map(|k| (probe[8 + k] - tip[k]).powi(2))
        .sum::<f32>()
        .sqrt();
    assert!(gap < 0.1, "probe box {gap} m from the tip");
    // The triangles in use index the vertices in use, which lie on the torso; the
    // rest is a finite fill.
    let triangles = f32_field(&spec, record, "torso_triangles");
    let used: Vec<&[f32]> = triangles.chunks_exact(3).filter(|t| t[0] >= 0.0).collect();
    assert!(used.len() > 1000);
    let count = used
        .iter()
        .flat_map(|t| t.iter())
        .fold(0.0f32, |a, &b| a.max(b)) as usize
        + 1;
    let vertices: Vec<&[f32]> = f32_field(&spec, record, "torso_vertices")
        .chunks_exact(4)
        .collect();
    assert!(count > 500 && count <= vertices.len());
    for v in &vertices[..count] {
        assert!(v[2] >= 0.79 && v[2] < 1.0, "vertex {v:?}");
    }
    assert!(
        vertices[count..]
            .iter()
            .all(|v| v.iter().all(|&x| x == 0.0))
    );
}

#[test]
fn pressing_shows_a_contact_point_under_the_face_and_an_indentation() {
    // The calibration press drives the probe into the skin's centre.
    let config = serde_json::json!({"scene_state": true});
    let (spec, _) = make("echogym/CalibrationPress-v0", config.clone());
    let trace = rollout("echogym/CalibrationPress-v0", config, 0, 1500);
    let pressed = trace.iter().rev().find(|(record, _)| {
        let c = f32_field(&spec, record, "scene_contact");
        c[6] == 1.0 && c[7] > 1.0
    });
    let (record, _) = pressed.expect("the press touched the skin");
    let contact = f32_field(&spec, record, "scene_contact");
    let tip = f32_field(&spec, record, "probe_pose");
    let off: f32 = (0..3)
        .map(|k| (contact[k] - tip[k]).powi(2))
        .sum::<f32>()
        .sqrt();
    assert!(off < 0.031, "contact point {off} m from the face centre");
    // The skin pushes the probe up.
    assert!(contact[5] > 0.5, "force {:?}", &contact[3..6]);
    let deepest = f32_field(&spec, record, "torso_vertices")
        .chunks_exact(4)
        .map(|v| v[3])
        .fold(f32::MIN, f32::max);
    assert!(deepest > 0.001, "deepest indentation {deepest} m");
}

#[test]
fn smooth_shading_renders_a_different_image_with_a_sky() {
    let camera = |shading: &str| {
        serde_json::json!({"cameras": [{"name": "view", "preset": "overview", "width": 64,
                                        "height": 48, "shading": shading}]})
    };
    let (spec, _) = make("echogym/UltrasoundScan-v0", camera("smooth"));
    let rgb = spec.field("view_rgb").unwrap();
    let smooth = rollout("echogym/UltrasoundScan-v0", camera("smooth"), 2, 1);
    let flat = rollout("echogym/UltrasoundScan-v0", camera("flat"), 2, 1);
    let image = |trace: &[(Vec<u8>, Vec<f32>)]| {
        trace[1].0[rgb.offset..rgb.offset + rgb.byte_len()].to_vec()
    };
    assert_ne!(image(&smooth), image(&flat));
    // Depth is the same measurement either way.
    let depth =
        |trace: &[(Vec<u8>, Vec<f32>)]| f32_field(&spec, &trace[1].0, "view_depth").to_vec();
    assert_eq!(depth(&smooth), depth(&flat));
    // Where nothing is hit the sky darkens upwards (the flat path's backdrop is uniform).
    let (pixels, d) = (image(&smooth), depth(&smooth));
    let sky: Vec<u8> = (0..48)
        .filter(|&row| d[row * 64] >= 10.0)
        .map(|row| pixels[row * 64 * 3 + 2])
        .collect();
    assert!(
        sky.len() >= 2 && sky.first() != sky.last(),
        "sky column {sky:?}"
    );
    // A preset that is not one is refused, naming it.
    let registry = EnvRegistry::default();
    let factory = registry.get("echogym/UltrasoundScan-v0").unwrap();
    let bad = serde_json::json!({"cameras": [{"name": "x", "preset": "nowhere"}]});
    let err = factory.spec(&map(bad)).unwrap_err().to_string();
    assert!(err.contains("cameras") && err.contains("nowhere"), "{err}");
}

#[test]
fn a_camera_with_every_holds_its_frame_between_renders() {
    let config = serde_json::json!({
        "cameras": [{"name": "probe", "width": 24, "height": 16, "rgb": false, "every": 3}],
    });
    let (spec, _) = make("echogym/UltrasoundScan-v0", config.clone());
    let trace = rollout("echogym/UltrasoundScan-v0", config, 5, 7);
    let depth = |k: usize| f32_field(&spec, &trace[k].0, "probe_depth").to_vec();
    // Rendered at steps 0, 3, 6; held at 1, 2, 4, 5 (the probe moves every step).
    assert_eq!(depth(1), depth(0));
    assert_eq!(depth(2), depth(0));
    assert_ne!(depth(3), depth(0));
    assert_eq!(depth(5), depth(3));
    assert_ne!(depth(6), depth(3));
}

#[test]
fn ultrasound_decimation_forms_an_image_every_n_steps() {
    // A pressing probe changes its image every step; with `every_n_steps: 5` the image
    // and `us_coupled` change only on steps 5, 10, ... and match the undecimated run there.
    let run = |every: usize| {
        let config = serde_json::json!({
            "task": {"site": "center", "hold_time": 0.2},
            "ultrasound": {"lines": 32, "rows": 64, "every_n_steps": every},
        });
        let (spec, mut env) = make("echogym/CalibrationPress-v0", config);
        let field = spec.field("ultrasound").unwrap().clone();
        let coupled = spec
            .info_keys
            .iter()
            .position(|k| k == "us_coupled")
            .unwrap();
        let mut record = vec![0u8; spec.obs_record_bytes];
        let mut info = vec![0.0f32; spec.info_keys.len()];
        env.reset(
            Some(3),
            &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
        );
        let mut trace = Vec::new();
        for _ in 0..600 {
            env.step(
                &vec![0.0; spec.action.size],
                &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
            );
            let image = record[field.offset..field.offset + field.byte_len()].to_vec();
            trace.push((image, info[coupled]));
        }
        trace
    };
    let (every, decimated) = (run(1), run(5));
    let changes = |t: &[(Vec<u8>, f32)]| t.windows(2).filter(|w| w[0] != w[1]).count();
    assert!(
        changes(&every) > 100,
        "the undecimated image changes while pressing"
    );
    for (k, (d, e)) in decimated.iter().zip(&every).enumerate() {
        let step = k + 1;
        if step % 5 == 0 {
            assert_eq!(
                d, e,
                "step {step}: decimated image differs where it is formed"
            );
        } else if step > 5 {
            assert_eq!(
                d,
                &decimated[k - 1],
                "step {step}: image changed between images"
            );
        }
    }
    let config = serde_json::json!({"ultrasound": {"every_n_steps": 0}});
    let registry = EnvRegistry::default();
    let err = registry
        .get("echogym/CalibrationPress-v0")
        .unwrap()
        .spec(&map(config))
        .unwrap_err()
        .to_string();
    assert!(err.contains("ultrasound.every_n_steps"), "{err}");
}
