//! The solver's behaviour, pinned: a fixed scripted press and slide of the Panda under
//! OSC on the default torso, compared step by step with a reference trace recorded by
//! the solver before the sparse-Cholesky change (tests/data/press_slide_trace.csv).
//!
//! The reference was written by this test with `ECHOGYM_WRITE_TRACE=1` on the
//! matrix-free Jacobi-CG torso (commit 8caae8e, the parent of this file's first commit).
//! Any later solver change must stay within [`FORCE_TOLERANCE`] / [`INDENT_TOLERANCE`]
//! of it; re-recording it is a behaviour change to state in the commit.

use echogym::sim::controller::{Osc, OscParams};
use echogym::sim::scene::{Scene, SceneParams};

const TRACE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../tests/data/press_slide_trace.csv"
);
/// Allowed difference of the F/T reading's z [N]: absolute plus relative part.
const FORCE_TOLERANCE: (f64, f64) = (0.05, 0.01);
/// Allowed difference of the deepest indentation [m]: absolute plus relative part.
const INDENT_TOLERANCE: (f64, f64) = (2e-5, 0.01);

/// One row every 5 physics steps (10 ms): time [s], F/T z [N], torso normal force [N],
/// deepest indentation of the torso [m].
fn press_slide() -> Vec<[f64; 4]> {
    let mut scene = Scene::new(SceneParams::default()).unwrap();
    let top = scene.torso().unwrap().params().top_z();
    let rot = scene.tip_pose().rotation;
    let mut osc = Osc::new(
        OscParams {
            kp: [300.0; 6],
            ..OscParams::default()
        },
        &scene,
    );
    let mut rows = Vec::new();
    // 1 s approach to 2 cm above the skin, 2 s press to 1 cm deep, 2 s slide at 4 cm/s.
    for k in 0..2500usize {
        let t = k as f64 * 0.002;
        let goal = if t < 1.0 {
            [0.0, -0.04, top + 0.02]
        } else if t < 3.0 {
            [0.0, -0.04, top + 0.02 - 0.03 * ((t - 1.0) / 2.0)]
        } else {
            [0.0, -0.04 + 0.04 * (t - 3.0), top - 0.01]
        };
        osc.set_goal(goal, rot);
        let tau = osc.torques(&mut scene);
        scene.step(&tau);
        if k % 5 == 4 {
            let torso = scene.torso().unwrap();
            let deepest = torso.displacements().iter().fold(0.0f64, |m, u| m.max(-u));
            rows.push([
                t + 0.002,
                scene.ft_reading()[2],
                scene.torso_wrench().normal_force,
                deepest,
            ]);
        }
    }
    rows
}

#[test]
fn press_slide_traces_match_the_reference() {
    let rows = press_slide();
    if std::env::var_os("ECHOGYM_WRITE_TRACE").is_some() {
        let mut out = String::from("t_s,ft_z_n,normal_force_n,indentation_m\n");
        for r in &rows {
            out += &format!("{:.3},{:.6},{:.6},{:.8}\n", r[0], r[1], r[2], r[3]);
        }
        std::fs::write(TRACE, out).unwrap();
    }
    let reference: Vec<[f64; 4]> = std::fs::read_to_string(TRACE)
        .unwrap()
        .lines()
        .skip(1)
        .map(|line| {
            let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect();
    assert_eq!(rows.len(), reference.len(), "trace length");
    let (mut worst_f, mut worst_u) = (0.0f64, 0.0f64);
    for (r, e) in rows.iter().zip(&reference) {
        let df = (r[1] - e[1]).abs();
        let du = (r[3] - e[3]).abs();
        worst_f = worst_f.max(df);
        worst_u = worst_u.max(du);
        assert!(
            df <= FORCE_TOLERANCE.0 + FORCE_TOLERANCE.1 * e[1].abs(),
            "F/T z at t = {} s: {} N vs reference {} N",
            e[0],
            r[1],
            e[1]
        );
        assert!(
            du <= INDENT_TOLERANCE.0 + INDENT_TOLERANCE.1 * e[3].abs(),
            "indentation at t = {} s: {} m vs reference {} m",
            e[0],
            r[3],
            e[3]
        );
    }
    // The script does press: the comparison is not of two idle traces.
    let peak = reference.iter().fold(0.0f64, |m, e| m.max(e[2]));
    assert!(peak > 5.0, "reference peak normal force {peak} N");
    eprintln!("worst |ΔF/T z| {worst_f:.4} N, worst |Δindentation| {worst_u:.2e} m");
}
