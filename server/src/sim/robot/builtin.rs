//! [`RobotKind`]: the arms shipped with echogym. Each is a URDF under
//! `server/assets/robots/` (sources cited in the file), compiled into the binary so a
//! daemon installed from a wheel needs no asset folder, plus the home pose URDF cannot
//! hold. Adding an arm: its URDF there, one variant and its two match arms here.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};
use std::sync::OnceLock;

use serde::{Deserialize, Serialize};

use super::model::RobotModel;
use super::urdf::load_urdf_str;

/// A built-in arm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum RobotKind {
    /// Franka Emika Panda (7 DoF), arm only, flange `panda_link8`.
    #[default]
    Panda,
    /// Universal Robots UR5e (6 DoF), flange `tool0`.
    Ur5e,
}

impl RobotKind {
    /// Every built-in arm.
    pub const ALL: [Self; 2] = [Self::Panda, Self::Ur5e];

    /// The URDF text.
    pub fn urdf(self) -> &'static str {
        match self {
            Self::Panda => include_str!("../../../assets/robots/panda.urdf"),
            Self::Ur5e => include_str!("../../../assets/robots/ur5e.urdf"),
        }
    }

    /// The home configuration \[rad\].
    pub fn home(self) -> &'static [f64] {
        match self {
            // Franka's start ("ready") pose, franka_ros franka_control/config/start_pose.yaml:
            // the flange at (0.3069, 0, 0.5903) m in panda_link0, its z axis straight down.
            Self::Panda => &[
                0.0,
                -FRAC_PI_4,
                0.0,
                -3.0 * FRAC_PI_4,
                0.0,
                FRAC_PI_2,
                FRAC_PI_4,
            ],
            // The seed's [0, -1.57, 1.57, -1.57, -1.57, 0] with exact π/2: tool0 at
            // (0.4919, 0.1333, 0.4879) m in base_link, its z axis straight down.
            Self::Ur5e => &[0.0, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, 0.0],
        }
    }

    /// The model, parsed once per process.
    pub fn model(self) -> RobotModel {
        static MODELS: [OnceLock<RobotModel>; RobotKind::ALL.len()] =
            [const { OnceLock::new() }; RobotKind::ALL.len()];
        MODELS[self as usize]
            .get_or_init(|| {
                let mut model =
                    load_urdf_str(self.urdf(), None).expect("built-in URDFs load (tested)");
                model.home = self.home().to_vec();
                model
            })
            .clone()
    }
}

#[cfg(test)]
mod tests {
    use rapier3d::na::{Rotation3, Unit, Vector3};

    use super::*;
    use crate::sim::robot::LinkSpec;

    /// Snapshots of the hand-typed Rust models (`panda.rs`, `ur5e.rs`, commit 9af4ca2) that
    /// the URDFs replaced, taken before they were deleted. A deliberate change to a
    /// built-in URDF updates its snapshot in the same commit.
    fn snapshot(kind: RobotKind) -> RobotModel {
        let text = match kind {
            RobotKind::Panda => include_str!("../../../../tests/data/robots/panda_model.toml"),
            RobotKind::Ur5e => include_str!("../../../../tests/data/robots/ur5e_model.toml"),
        };
        toml::from_str(text).expect("snapshot parses")
    }

    fn push(out: &mut Vec<(String, f64)>, key: &str, values: &[f64]) {
        for (i, v) in values.iter().enumerate() {
            out.push((format!("{key}[{i}]"), *v));
        }
    }

    fn push_link(out: &mut Vec<(String, f64)>, link: &LinkSpec) {
        let key = &link.name;
        push(out, &format!("{key}.mass"), &[link.mass]);
        push(out, &format!("{key}.com"), &link.com);
        push(out, &format!("{key}.inertia"), &link.inertia);
        for (k, c) in link.capsules.iter().enumerate() {
            push(out, &format!("{key}.capsule{k}.a"), &c.a);
            push(out, &format!("{key}.capsule{k}.b"), &c.b);
            push(out, &format!("{key}.capsule{k}.radius"), &[c.radius]);
        }
    }

    /// Every number of a model, keyed by link/joint name and field.
    fn numbers(model: &RobotModel) -> Vec<(String, f64)> {
        let mut out = Vec::new();
        push_link(&mut out, &model.base);
        for j in &model.joints {
            let key = &j.name;
            push(&mut out, &format!("{key}.origin_xyz"), &j.origin_xyz);
            push(&mut out, &format!("{key}.origin_rpy"), &j.origin_rpy);
            push(&mut out, &format!("{key}.axis"), &j.axis);
            let limits = [j.lower, j.upper, j.max_velocity, j.max_effort];
            push(&mut out, &format!("{key}.limits"), &limits);
            push(
                &mut out,
                &format!("{key}.damping_friction"),
                &[j.damping, j.friction],
            );
            push_link(&mut out, &j.link);
        }
        push(&mut out, "flange_xyz", &model.flange_xyz);
        push(&mut out, "flange_rpy", &model.flange_rpy);
        push(&mut out, "home", &model.home);
        out
    }

    /// Same names and structure; every number within 1e-12 and equal once rounded to
    /// rapier's f32, so the simulation cannot tell the two apart (capsule ends computed
    /// as centre ± length/2 differ from the typed ones by an ulp).
    fn assert_same(actual: &RobotModel, expected: &RobotModel) {
        assert_eq!(actual.name, expected.name);
        let (a, e) = (numbers(actual), numbers(expected));
        let keys = |v: &[(String, f64)]| v.iter().map(|(k, _)| k.clone()).collect::<Vec<_>>();
        assert_eq!(keys(&a), keys(&e), "structure of {}", expected.name);
        for ((key, x), (_, y)) in a.iter().zip(&e) {
            assert!(
                (x - y).abs() <= 1e-12 && (*x as f32) == (*y as f32),
                "{}: {key} = {x:?}, expected {y:?}",
                expected.name
            );
        }
    }

    /// Flange position \[m\] and z axis in the base frame at joint positions `q`, in f64.
    fn flange(model: &RobotModel, q: &[f64]) -> (Vector3<f64>, Vector3<f64>) {
        let rpy = |r: [f64; 3]| Rotation3::from_euler_angles(r[0], r[1], r[2]);
        let (mut rot, mut pos) = (Rotation3::identity(), Vector3::zeros());
        for (j, &qk) in model.joints.iter().zip(q) {
            pos += rot * Vector3::from(j.origin_xyz);
            let axis = Unit::new_normalize(Vector3::from(j.axis));
            rot = rot * rpy(j.origin_rpy) * Rotation3::from_axis_angle(&axis, qk);
        }
        pos += rot * Vector3::from(model.flange_xyz);
        rot *= rpy(model.flange_rpy);
        (pos, rot * Vector3::z())
    }

    fn assert_near(actual: Vector3<f64>, expected: [f64; 3], tol: f64) {
        assert!(
            (actual - Vector3::from(expected)).amax() < tol,
            "{actual:?} vs {expected:?}"
        );
    }

    #[test]
    fn urdf_models_equal_the_hand_typed_snapshots() {
        for kind in RobotKind::ALL {
            assert_same(&kind.model(), &snapshot(kind));
        }
    }

    /// Numbers quoted from the manufacturers' data and forward kinematics, independent of
    /// both the URDFs and the snapshots.
    #[test]
    fn built_in_arms_keep_their_published_numbers() {
        let panda = RobotKind::Panda.model();
        assert_eq!(panda.dof(), 7);
        assert_eq!(panda.joints[6].link.name, "panda_link7");
        let moving: f64 = panda.joints.iter().map(|j| j.link.mass).sum();
        assert!((moving - 13.78593).abs() < 1e-9, "{moving}");
        let efforts: Vec<f64> = panda.joints.iter().map(|j| j.max_effort).collect();
        assert_eq!(efforts, [87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]);
        assert_eq!(
            (panda.joints[3].lower, panda.joints[3].upper),
            (-3.0718, -0.0698)
        );
        assert!(
            panda
                .joints
                .iter()
                .all(|j| j.damping == 0.003 && j.friction == 0.2)
        );
        // Franka's ready pose: flange 0.107 m past link7, pointing straight down.
        let (pos, z) = flange(&panda, &panda.home);
        assert_near(pos, [0.3069, 0.0, 0.5903], 1e-4);
        assert_near(z, [0.0, 0.0, -1.0], 1e-12);

        let ur5e = RobotKind::Ur5e.model();
        assert_eq!(ur5e.dof(), 6);
        assert_eq!(ur5e.base.name, "base_link");
        assert_eq!(ur5e.base.mass, 4.0);
        let moving: f64 = ur5e.joints.iter().map(|j| j.link.mass).sum();
        assert!((moving - 17.7).abs() < 1e-9, "{moving}");
        let efforts: Vec<f64> = ur5e.joints.iter().map(|j| j.max_effort).collect();
        assert_eq!(efforts, [150.0, 150.0, 150.0, 28.0, 28.0, 28.0]);
        assert!(
            ur5e.joints
                .iter()
                .all(|j| j.damping == 0.0 && j.friction == 0.0)
        );
        // tool0 at q = 0 from the UR5e DH table, in base_link (UR's `base` turned by π):
        // x = a2 + a3, y = d4 + d6, z = d1 - d5.
        let (pos, _) = flange(&ur5e, &[0.0; 6]);
        assert_near(
            pos,
            [0.425 + 0.3922, 0.1333 + 0.0996, 0.1625 - 0.0997],
            1e-9,
        );
        assert_eq!((ur5e.flange_xyz, ur5e.flange_rpy), ([0.0; 3], [0.0; 3]));
        let (pos, z) = flange(&ur5e, &ur5e.home);
        assert_near(pos, [0.4919, 0.1333, 0.4879], 1e-4);
        assert_near(z, [0.0, 0.0, -1.0], 1e-9);
    }
}
