//! Validation of the physics core against physics, not eyeballing: gravity compensation
//! holds both arms still; the force-torque sensor reads the tool weight when free and the
//! commanded contact force in steady contact; a slow press gives a force–depth slope equal
//! to the torso's documented static stiffness; the probe does not feel the particle grid
//! (force ripple while sliding, uniform stiffness over the top); the OSC controller reaches
//! a 5 cm target within 1 s without overshoot; identical inputs give bitwise-identical
//! trajectories and snapshot → restore → step equals the uninterrupted run; the hybrid,
//! joint and action-level controllers track their goals; URDF arms load and hold still; the
//! torso is visible to ray casts.
//! (Energy decay of the passive torso and stability at 5× stiffness / 50 N are checked in
//! the torso's unit tests.)

use echogym::sim::controller::{Osc, OscParams};
use echogym::sim::robot::RobotKind;
use echogym::sim::scene::{Scene, SceneParams};
use echogym::sim::torso::{ProbeFace, ProbeKinematics, Torso, TorsoParams};
use rapier3d::na::DVector;

fn scene(robot: RobotKind, torso: bool) -> Scene {
    Scene::new(SceneParams {
        robot: robot.into(),
        torso: torso.then(TorsoParams::default),
        ..SceneParams::default()
    })
    .unwrap()
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn gravity_compensation_holds_both_arms_still() {
    for robot in [RobotKind::Panda, RobotKind::Ur5e] {
        let mut scene = scene(robot, false);
        let q0 = scene.arm().q(scene.world());
        for _ in 0..1000 {
            let tau = scene.gravity_torques();
            scene.step(&tau);
        }
        let drift = max_abs_diff(&scene.arm().q(scene.world()), &q0);
        assert!(drift < 1e-3, "{robot:?} drifted {drift} rad in 2 s");
    }
}

#[test]
fn free_probe_sensor_reads_the_tool_weight() {
    let mut scene = scene(RobotKind::Panda, false);
    for _ in 0..250 {
        let tau = scene.gravity_torques();
        scene.step(&tau);
    }
    let f = scene.ft_ideal();
    let norm = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
    let weight = 0.2 * 9.81;
    assert!(
        (norm - weight).abs() / weight < 0.02,
        "reads {norm} N, weight {weight} N"
    );
    // Home points the probe down: its +z (out of the face) is world -z, so the weight
    // loads the sensor along its +z.
    assert!(f[2] > 0.98 * weight, "{f:?}");
    assert!(!scene.in_contact());
}

/// Push the tip down with a commanded force `force(t)` by Jacobian transpose, holding
/// the other axes with OSC; returns (tip z, sensor fz minus weight) per step.
fn press(scene: &mut Scene, steps: usize, force: impl Fn(usize) -> f64) -> Vec<(f64, f64)> {
    let mut osc = Osc::new(
        OscParams {
            kp: [300.0, 300.0, 0.0, 300.0, 300.0, 300.0],
            ..OscParams::default()
        },
        scene,
    );
    let top = scene.torso().unwrap().params().top_z();
    let start = scene.tip_pose().translation;
    osc.set_goal(
        [start.x as f64, start.y as f64, top],
        scene.tip_pose().rotation,
    );
    let mut out = Vec::with_capacity(steps);
    for step in 0..steps {
        let mut tau = DVector::from_vec(osc.torques(scene));
        let tip = scene.tip_pose().translation;
        let arm = scene.arm().clone();
        let j = arm.point_jacobian(
            scene.world_mut(),
            [tip.x as f64, tip.y as f64, tip.z as f64],
        );
        let wrench = DVector::from_vec(vec![0.0, 0.0, -force(step), 0.0, 0.0, 0.0]);
        tau += j.transpose() * wrench;
        let tau: Vec<f64> = tau.iter().copied().collect();
        scene.step(&tau);
        // The sensor's z points out of the face (down): the skin pushing up reads negative,
        // the tool's weight positive.
        out.push((
            scene.tip_pose().translation.z as f64,
            -(scene.ft_ideal()[2] - 0.2 * 9.81),
        ));
    }
    out
}

/// Bring the probe just above the torso centre with OSC.
fn approach(robot: RobotKind) -> Scene {
    let mut scene = scene(robot, true);
    let top = scene.torso().unwrap().params().top_z();
    let mut osc = Osc::new(OscParams::default(), &scene);
    let rot = scene.tip_pose().rotation;
    osc.set_goal([0.0, 0.0, top + 0.002], rot);
    for _ in 0..1500 {
        let tau = osc.torques(&mut scene);
        scene.step(&tau);
    }
    let tip = scene.tip_pose().translation;
    assert!(
        (tip.z as f64 - top - 0.002).abs() < 2e-3,
        "approach ended at {tip:?}"
    );
    scene
}

#[test]
fn sensor_reads_the_commanded_contact_force_and_press_slope_matches_stiffness() {
    let mut scene = approach(RobotKind::Panda);
    let top = scene.torso().unwrap().params().top_z();
    // Quasi-static ramp to 8 N over 4 s, then hold for 1 s.
    let ramp = 2000;
    let trace = press(&mut scene, ramp + 500, |s| {
        8.0 * (s.min(ramp) as f64 / ramp as f64)
    });
    let (z_end, f_end) = *trace.last().unwrap();
    // Third law: the sensor reads (within 2 %) the force the probe puts into the torso.
    let torso_force = scene.torso_wrench().normal_force;
    assert!(
        (torso_force - f_end).abs() / f_end < 0.02,
        "torso {torso_force} vs sensor {f_end}"
    );
    // Joint friction (0.2 N·m per Panda joint) absorbs part of the commanded force.
    assert!(
        (f_end - 8.0).abs() / 8.0 < 0.10,
        "sensor {f_end} N vs commanded 8 N"
    );

    // Slope of force against depth over the loaded part of the ramp.
    let points: Vec<(f64, f64)> = trace[..ramp]
        .iter()
        .filter(|(_, f)| *f > 2.0)
        .map(|(z, f)| (top - z, *f))
        .collect();
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |a, p| (a.0 + p.0 / n, a.1 + p.1 / n));
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let slope = sxy / sxx;
    let tip = scene.tip_pose().translation;
    let documented = scene
        .torso()
        .unwrap()
        .static_probe_stiffness([tip.x as f64, tip.y as f64], top - z_end);
    assert!(
        (slope - documented).abs() / documented < 0.10,
        "press slope {slope} N/m vs documented {documented} N/m"
    );
}

fn kinematic_probe(x: f64, y: f64, z: f64, vy: f64) -> ProbeKinematics {
    ProbeKinematics::upright([x, y, z], [0.0, vy, 0.0])
}

#[test]
fn sliding_probe_does_not_feel_the_grid() {
    let mut torso = Torso::new(TorsoParams::default(), ProbeFace::default()).unwrap();
    let top = torso.params().top_z();
    let depth = 0.008;
    let speed = 0.04;
    let dt = 0.002;
    // Press in place, then slide 10 cm along the array's cross direction (x) and along y.
    for (dir, label) in [([1.0, 0.0], "across"), ([0.0, 1.0], "along")] {
        let mut torso_run = torso.clone();
        let start = [-0.05 * dir[0], -0.05 * dir[1]];
        for _ in 0..1500 {
            torso_run.step(
                dt,
                Some(&kinematic_probe(start[0], start[1], top - depth, 0.0)),
            );
        }
        let mut forces = Vec::new();
        for step in 0..((0.1 / speed / dt) as usize) {
            let s = step as f64 * speed * dt;
            let mut probe = kinematic_probe(
                start[0] + dir[0] * s,
                start[1] + dir[1] * s,
                top - depth,
                0.0,
            );
            probe.linear_velocity = [dir[0] * speed, dir[1] * speed, 0.0];
            let w = torso_run.step(dt, Some(&probe));
            if step > 250 {
                forces.push(w.normal_force);
            }
        }
        let mean = forces.iter().sum::<f64>() / forces.len() as f64;
        let (lo, hi) = forces
            .iter()
            .fold((f64::MAX, f64::MIN), |a, f| (a.0.min(*f), a.1.max(*f)));
        let ripple = (hi - lo) / mean;
        assert!(
            ripple <= 0.15,
            "sliding {label}: ripple {:.1} % of {mean:.2} N",
            ripple * 100.0
        );
    }
    torso.step(dt, None);
}

#[test]
fn stiffness_is_uniform_over_the_top() {
    let torso = Torso::new(TorsoParams::default(), ProbeFace::default()).unwrap();
    let p = torso.params();
    let (hx, hy) = (
        p.size[0] / 2.0 - 0.04 - 0.005,
        p.size[1] / 2.0 - 0.04 - 0.03,
    );
    let mut values = Vec::new();
    for i in 0..7 {
        for j in 0..7 {
            let x = p.center_xy[0] - hx + 2.0 * hx * i as f64 / 6.0;
            let y = p.center_xy[1] - hy + 2.0 * hy * j as f64 / 6.0;
            values.push(torso.static_probe_stiffness([x, y], 0.005));
        }
    }
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    let worst = values
        .iter()
        .map(|k| (k - mean).abs() / mean)
        .fold(0.0, f64::max);
    assert!(
        worst <= 0.10,
        "stiffness varies by {:.1} % around {mean:.0} N/m",
        worst * 100.0
    );
}

#[test]
fn osc_reaches_a_5_cm_target_within_1_s_without_overshoot() {
    for robot in [RobotKind::Panda, RobotKind::Ur5e] {
        let mut scene = scene(robot, false);
        let mut osc = Osc::new(OscParams::default(), &scene);
        let start = scene.tip_pose().translation;
        osc.set_goal_delta(&scene, [0.05, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let mut max_progress: f64 = 0.0;
        let mut reached_at = None;
        for step in 0..1000 {
            let tau = osc.torques(&mut scene);
            scene.step(&tau);
            let progress = (scene.tip_pose().translation.x - start.x) as f64;
            max_progress = max_progress.max(progress);
            if reached_at.is_none() && (progress - 0.05).abs() < 0.0025 {
                reached_at = Some(step);
            }
        }
        let end = (scene.tip_pose().translation.x - start.x) as f64;
        println!("{robot:?}: reached at {reached_at:?}, end {end}, max {max_progress}");
        assert!(
            reached_at.is_some(),
            "{robot:?} did not reach within 1 s (at {end} m)"
        );
        assert!((end - 0.05).abs() < 0.0025, "{robot:?} ended at {end}");
        assert!(
            max_progress <= 0.055,
            "{robot:?} overshot to {max_progress} m"
        );
    }
}

/// The controllers read the arm's Jacobians and mass matrix as rapier left them after a
/// step instead of recomputing forward kinematics (`Scene::arm_kinematics`); this holds
/// only while rapier's step ends with the kinematics current, which a rapier upgrade could
/// change.
#[test]
fn the_arms_cached_kinematics_are_current_after_every_step() {
    for robot in [RobotKind::Panda, RobotKind::Ur5e] {
        let mut scene = scene(robot, true);
        let mut osc = Osc::new(OscParams::default(), &scene);
        osc.set_goal_delta(&scene, [0.02, 0.03, -0.15, 0.0, 0.3, 0.0]);
        for step in 0..300 {
            let tau = osc.torques(&mut scene);
            scene.step(&tau);
            let t = scene.tip_pose().translation;
            let tip = [t.x as f64, t.y as f64, t.z as f64];
            let arm = scene.arm();
            let cached = (
                arm.point_jacobian(scene.world(), tip),
                arm.mass_matrix(scene.world()),
            );
            let mut refreshed = scene.world().clone();
            arm.update_kinematics(&mut refreshed);
            let fresh = (
                arm.point_jacobian(&refreshed, tip),
                arm.mass_matrix(&refreshed),
            );
            assert_eq!(cached, fresh, "{robot:?}, step {step}");
        }
        // A heavier probe moves the last link's centre of mass: the next read refreshes.
        scene.set_probe_mass(1.5);
        let (arm, world) = scene.arm_kinematics();
        let read = arm.mass_matrix(world);
        let mut refreshed = world.clone();
        arm.update_kinematics(&mut refreshed);
        assert_eq!(
            read,
            arm.mass_matrix(&refreshed),
            "{robot:?} after a mass change"
        );
    }
}

fn rollout(scene: &mut Scene, steps: usize) -> Vec<f64> {
    let mut osc = Osc::new(OscParams::default(), scene);
    osc.set_goal_delta(scene, [0.02, 0.03, -0.15, 0.0, 0.0, 0.0]);
    let mut out = Vec::new();
    for _ in 0..steps {
        let tau = osc.torques(scene);
        scene.step(&tau);
        out.extend(scene.arm().q(scene.world()));
        out.extend(scene.ft_ideal());
    }
    out
}

#[test]
fn identical_inputs_give_bitwise_identical_trajectories_and_snapshots_restore() {
    let mut a = scene(RobotKind::Panda, true);
    let mut b = scene(RobotKind::Panda, true);
    let ta = rollout(&mut a, 300);
    let tb = rollout(&mut b, 300);
    assert!(ta.iter().zip(&tb).all(|(x, y)| x.to_bits() == y.to_bits()));

    let snapshot = a.clone();
    let continued = rollout(&mut a, 200);
    let mut restored = snapshot.clone();
    let replayed = rollout(&mut restored, 200);
    assert!(
        continued
            .iter()
            .zip(&replayed)
            .all(|(x, y)| x.to_bits() == y.to_bits())
    );
}

#[test]
fn torso_is_visible_to_ray_casts_and_follows_the_skin() {
    let mut scene = Scene::new(SceneParams {
        torso_collider_sync: true,
        ..SceneParams::default()
    })
    .unwrap();
    let tau = scene.gravity_torques();
    scene.step(&tau);
    let top = scene.torso().unwrap().params().top_z();
    let torso = scene.torso_collider().unwrap();
    let (hit, distance) = scene
        .world()
        .cast_ray([0.05, 0.1, 1.2], [0.0, 0.0, -1.0], 1.0)
        .unwrap();
    assert_eq!(hit, torso);
    assert!(
        (1.2 - distance - top).abs() < 1e-4,
        "hit at z = {}",
        1.2 - distance
    );
    // Press the skin with a kinematic probe: the ray now ends lower.
    for _ in 0..500 {
        let probe = kinematic_probe(0.05, 0.1, top - 0.01, 0.0);
        scene.torso_mut().unwrap().step(0.002, Some(&probe));
    }
    let skin = scene.torso().unwrap().skin_z(0.05, 0.1).unwrap();
    assert!(skin < top - 0.008, "skin at {skin}");
    let tau = scene.gravity_torques();
    scene.step(&tau); // syncs the collider; rapier refits its tree
    let (hit, distance) = scene
        .world()
        .cast_ray([0.05, 0.1, 1.2], [0.0, 0.0, -1.0], 1.0)
        .unwrap();
    assert_eq!(hit, torso);
    let z = 1.2 - distance;
    assert!(
        z < top - 0.007 && z > skin - 0.002,
        "ray hit at z = {z}, skin at {skin}"
    );
}

#[test]
fn hybrid_controller_holds_5_n_while_sliding() {
    use echogym::sim::controller::HybridForceMotion;
    let mut scene = approach(RobotKind::Panda);
    let mut hybrid = HybridForceMotion::new(OscParams::default(), &scene, 5.0);
    let rot = scene.tip_pose().rotation;
    let mut forces = Vec::new();
    for step in 0..2500 {
        // Settle for 1 s, then slide 4 cm along y at 4 cm/s.
        let y = if step < 500 {
            0.0
        } else {
            0.04 * ((step - 500) as f64 * 0.002).min(1.0)
        };
        let top = scene.torso().unwrap().params().top_z();
        hybrid.motion.set_goal([0.0, y, top], rot);
        let tau = hybrid.torques(&mut scene);
        scene.step(&tau);
        if step >= 750 {
            forces.push(HybridForceMotion::measured_force(&scene));
        }
    }
    let mean = forces.iter().sum::<f64>() / forces.len() as f64;
    let worst = forces.iter().map(|f| (f - 5.0).abs()).fold(0.0, f64::max);
    assert!((mean - 5.0).abs() < 0.1, "mean force {mean} N");
    assert!(worst < 1.0, "force left 5 ± 1 N: worst error {worst} N");
    let y = scene.tip_pose().translation.y as f64;
    assert!((y - 0.04).abs() < 0.005, "slid to y = {y}");
}

#[test]
fn joint_controllers_track_their_goals() {
    use echogym::sim::controller::{JointPosition, JointVelocity};
    let mut scene = scene(RobotKind::Ur5e, false);
    let mut position = JointPosition::new(&scene);
    position.goal[0] += 0.2;
    for _ in 0..1000 {
        let tau = position.torques(&mut scene);
        scene.step(&tau);
    }
    let q = scene.arm().q(scene.world());
    assert!(
        (q[0] - position.goal[0]).abs() < 2e-3,
        "q0 = {}, goal {}",
        q[0],
        position.goal[0]
    );
    let mut velocity = JointVelocity::new(&scene);
    velocity.goal[1] = 0.3;
    for _ in 0..250 {
        let tau = velocity.torques(&mut scene);
        scene.step(&tau);
    }
    let qd = scene.arm().qd(scene.world());
    assert!((qd[1] - 0.3).abs() < 0.01, "qd1 = {}", qd[1]);
}

#[test]
fn urdf_arms_load_merge_fixed_joints_and_hold_still() {
    use echogym::sim::robot::{RobotConfig, UrdfRobot, load_urdf};
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/three_link_arm.urdf");
    let model = load_urdf(&path, None).unwrap();
    assert_eq!(model.dof(), 3);
    // The fixed base mount folds into the first joint's origin, the housing's 0.5 kg into
    // link2, the trailing tool0 becomes the flange.
    assert!((model.joints[0].origin_xyz[2] - 0.15).abs() < 1e-12);
    assert!((model.joints[1].link.mass - 1.7).abs() < 1e-12);
    assert!((model.flange_xyz[0] - 0.2).abs() < 1e-12);
    assert_eq!(model.home, vec![0.0, 0.0, 1.35]);
    assert_eq!(model.joints[1].link.capsules.len(), 2);

    let mut scene = Scene::new(SceneParams {
        robot: RobotConfig::Urdf(UrdfRobot::new(path)),
        torso: None,
        ..SceneParams::default()
    })
    .unwrap();
    let q0 = scene.arm().q(scene.world());
    for _ in 0..1000 {
        let tau = scene.gravity_torques();
        scene.step(&tau);
    }
    let drift = max_abs_diff(&scene.arm().q(scene.world()), &q0);
    assert!(drift < 1e-3, "URDF arm drifted {drift} rad");
    let bad = Scene::new(SceneParams {
        robot: RobotConfig::Urdf(UrdfRobot::new("/nonexistent.urdf")),
        ..SceneParams::default()
    });
    assert!(bad.unwrap_err().to_string().contains("/nonexistent.urdf"));
}

#[test]
fn actions_are_scaled_by_the_seeds_limits_at_the_control_frequency() {
    use echogym::sim::controller::{
        ArmController, ControllerConfig, ControllerKind, ImpedanceMode,
    };
    let config = ControllerConfig::default();
    assert_eq!(config.physics_steps_per_action(0.002), 25);
    assert_eq!(config.action_size(7), 6);
    let variable = ControllerConfig {
        impedance_mode: ImpedanceMode::Variable,
        ..ControllerConfig::default()
    };
    assert_eq!(variable.action_size(7), 18);
    assert_eq!(
        ControllerConfig {
            kind: ControllerKind::JointTorque,
            ..config.clone()
        }
        .action_size(6),
        6
    );

    let mut panda = scene(RobotKind::Panda, false);
    let start = panda.tip_pose().translation;
    let mut controller = ArmController::new(config, &panda);
    // Full-scale +x actions (clipped from 3.0) for 1 s: each moves the goal 5 cm.
    for _ in 0..20 {
        controller.act(&mut panda, &[3.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    }
    let moved = (panda.tip_pose().translation.x - start.x) as f64;
    assert!(moved > 0.2 && moved < 1.0, "moved {moved} m in 20 actions");
    assert!((panda.time() - 1.0).abs() < 1e-9);

    for kind in [
        ControllerKind::JointPosition,
        ControllerKind::JointVelocity,
        ControllerKind::JointTorque,
    ] {
        let mut ur5e = scene(RobotKind::Ur5e, false);
        let cfg = ControllerConfig {
            kind,
            ..ControllerConfig::default()
        };
        let mut controller = ArmController::new(cfg.clone(), &ur5e);
        let q0 = ur5e.arm().q(ur5e.world());
        let mut action = vec![0.0; cfg.action_size(ur5e.arm().dof())];
        action[0] = 0.5;
        for _ in 0..4 {
            controller.act(&mut ur5e, &action);
        }
        let q = ur5e.arm().q(ur5e.world());
        assert!(
            q[0] - q0[0] > 0.01,
            "{kind:?}: joint 0 moved {}",
            q[0] - q0[0]
        );
    }
}
