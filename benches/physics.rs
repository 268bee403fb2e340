//! `benches/run physics` (Rust side): physics steps/s on one core for echogym's scenes,
//! and the particle-torso design alternative, printed as one JSON object.
//!
//! Scenes (2 ms steps):
//! - `torso_press`: the torso alone under a kinematic probe pressing 8 mm and sliding
//!   (the solver works every step; a torso at rest costs almost nothing);
//! - `torso_press_2x`: the same with about twice the particles (scaling check);
//! - `torso_replay`: the same press on the torso a calibration replays (10 % of the
//!   particle mass, the same N/m: `calibrate::replay::MASS_SHARE`), whose worse-conditioned
//!   solve is most of `echogym calibrate`'s time;
//! - `torso_rigid_bodies`: design B — the same particles as rapier rigid bodies (locked to
//!   slide along their normal, our springs as forces, contacts by rapier);
//! - `arm_alone`: the Panda holding its pose with gravity compensation recomputed each step;
//! - `arm_press_slide`: the Panda pressing the probe 1 cm into the torso and sliding it
//!   ±8 cm at 4 cm/s under OSC recomputed every step (controller cost included).
//!   `--export-scene PATH` also writes the scene for the MuJoCo side (physics_mujoco.py).

use std::time::Instant;

use echogym::calibrate::replay::MASS_SHARE;
use echogym::sim::controller::{Osc, OscParams};
use echogym::sim::robot::RobotKind;
use echogym::sim::scene::{Scene, SceneParams};
use echogym::sim::torso::{ProbeFace, ProbeKinematics, Torso, TorsoParams};
use rapier3d::prelude::*;
use serde_json::{Value, json};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Steps/s of `step` run for `seconds` (after `warmup` steps), median of `repeats`.
fn rate(
    repeats: usize,
    seconds: f64,
    mut make: impl FnMut() -> Box<dyn FnMut()>,
) -> (f64, Vec<f64>) {
    let mut runs = Vec::new();
    for _ in 0..repeats {
        let mut step = make();
        for _ in 0..200 {
            step();
        }
        let start = Instant::now();
        let mut n = 0u64;
        while start.elapsed().as_secs_f64() < seconds {
            for _ in 0..50 {
                step();
            }
            n += 50;
        }
        runs.push(n as f64 / start.elapsed().as_secs_f64());
    }
    (median(runs.clone()), runs)
}

fn probe_at(x: f64, y: f64, z: f64, vy: f64) -> ProbeKinematics {
    ProbeKinematics::upright([x, y, z], [0.0, vy, 0.0])
}

/// The torso under a probe pressing 8 mm and sliding ±8 cm along y at 4 cm/s.
fn torso_press(params: TorsoParams) -> Box<dyn FnMut()> {
    let mut torso = Torso::new(params, ProbeFace::default()).unwrap();
    let top = torso.params().top_z();
    let mut t = 0.0f64;
    Box::new(move || {
        let phase = (t * 0.04 / 0.16).fract();
        let (y, vy) = if phase < 0.5 {
            (-0.08 + 0.32 * phase, 0.04)
        } else {
            (0.24 - 0.32 * phase, -0.04)
        };
        torso.step(0.002, Some(&probe_at(0.0, y, top - 0.008, vy)));
        t += 0.002;
    })
}

/// Design B: the torso's particles as rapier rigid bodies.
fn torso_rigid_bodies(params: &TorsoParams) -> (Box<dyn FnMut()>, usize) {
    let torso = Torso::new(params.clone(), ProbeFace::default()).unwrap();
    let layout = torso.layout().clone();
    let mass = torso.masses().to_vec();
    let stiffness = params.stiffness;
    let edge_k = params.winkler_modulus() * params.smoothing_length.powi(2);
    let mut bodies = RigidBodySet::new();
    let mut colliders = ColliderSet::new();
    let mut handles = Vec::new();
    for (i, p) in layout.rest.iter().enumerate() {
        let n = layout.normal[i];
        let mut locked = LockedAxes::ROTATION_LOCKED;
        let dominant = (0..3)
            .max_by(|a, b| n[*a].abs().total_cmp(&n[*b].abs()))
            .unwrap();
        for (axis, flag) in [
            LockedAxes::TRANSLATION_LOCKED_X,
            LockedAxes::TRANSLATION_LOCKED_Y,
            LockedAxes::TRANSLATION_LOCKED_Z,
        ]
        .into_iter()
        .enumerate()
        {
            if axis != dominant {
                locked |= flag;
            }
        }
        let h = bodies.insert(
            RigidBodyBuilder::dynamic()
                .translation(Vector::new(p[0] as Real, p[1] as Real, p[2] as Real))
                .locked_axes(locked)
                .gravity_scale(0.0)
                .linear_damping(params.damping as Real),
        );
        colliders.insert_with_parent(
            ColliderBuilder::ball(0.004)
                .mass(mass[i] as Real)
                .collision_groups(InteractionGroups::new(
                    Group::GROUP_1,
                    Group::GROUP_2,
                    InteractionTestMode::And,
                )),
            h,
            &mut bodies,
        );
        handles.push(h);
    }
    let top = params.top_z() as Real;
    let probe = bodies.insert(
        RigidBodyBuilder::kinematic_position_based().translation(Vector::new(
            0.0,
            -0.08,
            top + 0.05 - 0.008,
        )),
    );
    colliders.insert_with_parent(
        ColliderBuilder::cuboid(0.005, 0.03, 0.05).collision_groups(InteractionGroups::new(
            Group::GROUP_2,
            Group::GROUP_1,
            InteractionTestMode::And,
        )),
        probe,
        &mut bodies,
    );
    let n = handles.len();
    let mut state = (
        IntegrationParameters {
            dt: 0.002,
            ..IntegrationParameters::default()
        },
        IslandManager::new(),
        BroadPhaseBvh::new(),
        NarrowPhase::new(),
        ImpulseJointSet::new(),
        MultibodyJointSet::new(),
        SoftBodySet::new(),
        CCDSolver::new(),
        PhysicsPipeline::new(),
    );
    let mut t = 0.0f64;
    let step = move || {
        // Springs to rest and to neighbours, as explicit forces along each normal.
        let u: Vec<f64> = (0..n)
            .map(|i| {
                let p = bodies[handles[i]].translation();
                let r = layout.rest[i];
                let nn = layout.normal[i];
                (p.x as f64 - r[0]) * nn[0]
                    + (p.y as f64 - r[1]) * nn[1]
                    + (p.z as f64 - r[2]) * nn[2]
            })
            .collect();
        let mut f: Vec<f64> = (0..n).map(|i| -mass[i] * stiffness * u[i]).collect();
        for &(i, j, w) in &layout.edges {
            let s = edge_k * w * (u[i] - u[j]);
            f[i] -= s;
            f[j] += s;
        }
        for i in 0..n {
            let nn = layout.normal[i];
            let body = &mut bodies[handles[i]];
            body.reset_forces(false);
            body.add_force(
                Vector::new(
                    (f[i] * nn[0]) as Real,
                    (f[i] * nn[1]) as Real,
                    (f[i] * nn[2]) as Real,
                ),
                true,
            );
        }
        let phase = (t * 0.04 / 0.16).fract();
        let y = if phase < 0.5 {
            -0.08 + 0.32 * phase
        } else {
            0.24 - 0.32 * phase
        };
        bodies[probe].set_next_kinematic_translation(Vector::new(
            0.0,
            y as Real,
            top + 0.05 - 0.008,
        ));
        let (ip, islands, bp, np, ij, mj, sb, ccd, pipe) = &mut state;
        pipe.step(
            Vector::new(0.0, 0.0, -9.81),
            ip,
            islands,
            bp,
            np,
            &mut bodies,
            &mut colliders,
            ij,
            mj,
            sb,
            ccd,
            &(),
            &(),
        );
        t += 0.002;
    };
    (Box::new(step), n)
}

/// The Panda holding its pose with gravity compensation recomputed every step.
fn arm_alone() -> Box<dyn FnMut()> {
    let mut scene = Scene::new(SceneParams {
        torso: None,
        ..SceneParams::default()
    })
    .unwrap();
    Box::new(move || {
        let tau = scene.gravity_torques();
        scene.step(&tau);
    })
}

/// The Panda pressing 1 cm and sliding ±8 cm at 4 cm/s under OSC (after an untimed approach).
fn arm_press_slide() -> (Box<dyn FnMut()>, f64) {
    let mut scene = Scene::new(SceneParams::default()).unwrap();
    let top = scene.torso().unwrap().params().top_z();
    let rot = scene.tip_pose().rotation;
    let mut osc = Osc::new(
        OscParams {
            kp: [300.0, 300.0, 300.0, 300.0, 300.0, 300.0],
            ..OscParams::default()
        },
        &scene,
    );
    osc.set_goal([0.0, -0.08, top + 0.02], rot);
    for _ in 0..1500 {
        let tau = osc.torques(&mut scene);
        scene.step(&tau);
    }
    osc.set_goal([0.0, -0.08, top - 0.01], rot);
    for _ in 0..1000 {
        let tau = osc.torques(&mut scene);
        scene.step(&tau);
    }
    let force = scene.torso_wrench().normal_force;
    let mut t = 0.0f64;
    let step = Box::new(move || {
        let phase = (t * 0.04 / 0.32).fract();
        let y = if phase < 0.5 {
            -0.08 + 0.32 * phase
        } else {
            0.24 - 0.32 * phase
        };
        osc.set_goal([0.0, y, top - 0.01], rot);
        let tau = osc.torques(&mut scene);
        scene.step(&tau);
        t += 0.002;
    });
    (step, force)
}

fn export_scene(path: &str, torso: &Torso) {
    let model = RobotKind::Panda.model();
    let params = SceneParams::default();
    let t = torso.params();
    let robot = json!({
        "name": model.name,
        "base_pos": params.robot_base,
        "base_rpy": [0.0, 0.0, params.robot_base_yaw],
        "joints": model.joints.iter().map(|j| json!({
            "name": j.name, "origin_xyz": j.origin_xyz, "origin_rpy": j.origin_rpy, "axis": j.axis,
            "lower": j.lower, "upper": j.upper, "damping": j.damping,
            "link": {"name": j.link.name, "mass": j.link.mass, "com": j.link.com, "inertia": j.link.inertia,
                     "capsules": j.link.capsules.iter().map(|c| json!({"a": c.a, "b": c.b, "radius": c.radius})).collect::<Vec<_>>()}
        })).collect::<Vec<_>>(),
        "flange_xyz": model.flange_xyz, "flange_rpy": model.flange_rpy, "home": model.home,
    });
    let n = torso.layout().len();
    let total_mass: f64 = torso.masses().iter().sum();
    // A solid flex grid with about as many vertices as our shell has particles.
    let scene = json!({
        "dt": params.world.dt, "gravity": params.world.gravity,
        "table": {"center": [params.world.table.center_xy[0], params.world.table.center_xy[1], params.world.table.top_z - params.world.table.half_extents[2]],
                  "half_extents": params.world.table.half_extents},
        "torso": {"center_xy": t.center_xy, "bottom_z": t.bottom_z, "size": t.size, "grid": [10, 13, 5],
                  "particle_count": n, "particle_mass": total_mass / 650.0, "particle_radius": 0.004,
                  "stiffness": t.stiffness, "damping": t.damping},
        "robot": robot,
        "probe": {"half_extents": [0.005, 0.03, 0.05], "mass": params.probe.mass, "tip_offset": params.probe.length},
        "press_slide": {"depth": 0.01, "speed": 0.04, "travel": 0.08},
    });
    std::fs::write(path, serde_json::to_string_pretty(&scene).unwrap()).unwrap();
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let value = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let seconds: f64 = value("--seconds").map_or(2.0, |v| v.parse().unwrap());
    let repeats: usize = value("--repeats").map_or(3, |v| v.parse().unwrap());
    let default = TorsoParams::default();
    let torso = Torso::new(default.clone(), ProbeFace::default()).unwrap();
    if let Some(path) = value("--export-scene") {
        export_scene(&path, &torso);
    }
    let particles = torso.layout().len();
    let double = TorsoParams {
        spacing: default.spacing / 2f64.sqrt(),
        ..default.clone()
    };
    let particles_2x = Torso::new(double.clone(), ProbeFace::default())
        .unwrap()
        .layout()
        .len();

    let replay = TorsoParams {
        density: default.density * MASS_SHARE,
        stiffness: default.stiffness / MASS_SHARE,
        damping: default.damping / MASS_SHARE,
        ..default.clone()
    };

    let mut out = serde_json::Map::new();
    let (r, runs) = rate(repeats, seconds, || torso_press(replay.clone()));
    out.insert(
        "torso_replay".into(),
        json!({"steps_per_s": r, "runs": runs, "particles": particles, "mass_share": MASS_SHARE}),
    );
    let (r, runs) = rate(repeats, seconds, || torso_press(default.clone()));
    out.insert("torso_press".into(), json!({"steps_per_s": r, "runs": runs, "particles": particles, "dofs": particles, "bodies": 0}));
    let (r, runs) = rate(repeats, seconds, || torso_press(double.clone()));
    out.insert("torso_press_2x".into(), json!({"steps_per_s": r, "runs": runs, "particles": particles_2x, "dofs": particles_2x, "bodies": 0}));
    let mut design_b_particles = 0;
    let (r, runs) = rate(repeats.min(2), seconds, || {
        let (step, n) = torso_rigid_bodies(&default);
        design_b_particles = n;
        step
    });
    out.insert("torso_rigid_bodies".into(), json!({"steps_per_s": r, "runs": runs, "particles": design_b_particles, "bodies": design_b_particles + 1, "dofs": design_b_particles}));
    let (r, runs) = rate(repeats, seconds, arm_alone);
    out.insert(
        "arm_alone".into(),
        json!({"steps_per_s": r, "runs": runs, "bodies": 9, "dofs": 7}),
    );
    let mut force = 0.0;
    let (r, runs) = rate(repeats, seconds, || {
        let (step, f) = arm_press_slide();
        force = f;
        step
    });
    out.insert("arm_press_slide".into(), json!({"steps_per_s": r, "runs": runs, "bodies": 9, "dofs": 7 + particles, "particles": particles, "press_force_n": force}));
    println!("{}", Value::Object(out));
}
