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

    /// The home configuration [rad].
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
    use super::*;
    use crate::sim::robot::{LinkSpec, panda, ur5e};

    /// Snapshots of the hand-typed Rust models the URDFs replaced.
    fn fixture(kind: RobotKind) -> RobotModel {
        let text = match kind {
            RobotKind::Panda => include_str!("../../../../tests/data/robots/panda_model.toml"),
            RobotKind::Ur5e => include_str!("../../../../tests/data/robots/ur5e_model.toml"),
        };
        toml::from_str(text).expect("fixture parses")
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
    /// rapier's f32, so the simulation cannot tell the two apart.
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

    #[test]
    fn urdf_models_equal_the_hand_typed_ones() {
        assert_same(&RobotKind::Panda.model(), &panda());
        assert_same(&RobotKind::Ur5e.model(), &ur5e());
    }

    #[test]
    fn urdf_models_equal_their_snapshots() {
        for kind in RobotKind::ALL {
            assert_same(&kind.model(), &fixture(kind));
        }
    }

    #[test]
    fn hand_typed_models_equal_their_snapshots() {
        assert_eq!(panda(), fixture(RobotKind::Panda));
        assert_eq!(ur5e(), fixture(RobotKind::Ur5e));
    }

    #[test]
    #[ignore = "writes the snapshots"]
    fn write_snapshots() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/robots");
        std::fs::create_dir_all(&dir).unwrap();
        for (name, model) in [("panda", panda()), ("ur5e", ur5e())] {
            let text = toml::to_string(&model).unwrap();
            std::fs::write(dir.join(format!("{name}_model.toml")), text).unwrap();
        }
    }
}
