//! [`RobotConfig`]: which arm a scene holds, as configs write it: a built-in arm by name
//! (`"panda"`), or the user's URDF with what URDF does not say (where the tool mounts,
//! the home pose): `{urdf = "/path/arm.urdf", tool_offset = [0, 0, 0.05], home = [...]}`.

use std::fmt;
use std::path::PathBuf;

use rapier3d::na::{Rotation3, Vector3};
use serde::de::{self, IntoDeserializer, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize};

use super::builtin::RobotKind;
use super::model::RobotModel;
use super::urdf::{UrdfError, load_urdf};

/// Which arm: a built-in one or a URDF file.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum RobotConfig {
    /// A built-in arm, written as its name (`"panda"`, `"ur5e"`).
    Builtin(RobotKind),
    /// An arm loaded from a URDF file, written as a table.
    Urdf(UrdfRobot),
}

impl Default for RobotConfig {
    /// The Panda.
    fn default() -> Self {
        Self::Builtin(RobotKind::default())
    }
}

impl From<RobotKind> for RobotConfig {
    fn from(kind: RobotKind) -> Self {
        Self::Builtin(kind)
    }
}

/// An arm from a URDF file (a serial chain; see [`super::load_urdf`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UrdfRobot {
    /// The URDF file, read by the server (relative paths from the server's working
    /// directory).
    pub urdf: PathBuf,
    /// The link whose frame is the flange. Default: the leaf reached through the most
    /// moving joints (e.g. `tool0`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool_link: Option<String>,
    /// Where the probe's back face mounts, in the flange frame \[m\] (e.g. a holder's length
    /// along the tool axis z). Default 0: on the flange.
    #[serde(default)]
    pub tool_offset: [f64; 3],
    /// Orientation of the mount in the flange frame, fixed-axis roll-pitch-yaw \[rad\]; the
    /// probe points along the mount's z. Default 0.
    #[serde(default)]
    pub tool_rpy: [f64; 3],
    /// Start configuration \[rad\], one value per moving joint, within the limits. Default:
    /// 0 for each joint, or the middle of its range when 0 is outside it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub home: Option<Vec<f64>>,
}

impl UrdfRobot {
    /// The URDF at `urdf` with the flange as the tool mount and the default home.
    pub fn new(urdf: impl Into<PathBuf>) -> Self {
        Self {
            urdf: urdf.into(),
            tool_link: None,
            tool_offset: [0.0; 3],
            tool_rpy: [0.0; 3],
            home: None,
        }
    }
}

/// A configured arm could not be built into a model.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RobotConfigError {
    /// The URDF could not be read or is not a serial arm.
    #[error(transparent)]
    Urdf(#[from] UrdfError),
    /// `home` does not have one value per joint.
    #[error("home has {got} values for the {dof} joints of {model}")]
    HomeLength {
        /// The model name.
        model: String,
        /// Its joints.
        dof: usize,
        /// The values given.
        got: usize,
    },
    /// A `home` value is outside its joint's limits (or not finite).
    #[error("home value {value} rad of joint {joint} is outside its limits [{lower}, {upper}] rad")]
    HomeOutOfRange {
        /// The joint.
        joint: String,
        /// The value given \[rad\].
        value: f64,
        /// Lower limit \[rad\].
        lower: f64,
        /// Upper limit \[rad\].
        upper: f64,
    },
    /// `tool_offset` or `tool_rpy` is not finite.
    #[error("tool_offset and tool_rpy must be finite")]
    NonFiniteTool,
}

impl RobotConfig {
    /// The model (reads the URDF file for [`RobotConfig::Urdf`]).
    pub fn model(&self) -> Result<RobotModel, RobotConfigError> {
        match self {
            Self::Builtin(kind) => Ok(kind.model()),
            Self::Urdf(robot) => robot.model(),
        }
    }
}

impl UrdfRobot {
    /// Load the URDF and apply the tool mount and home pose.
    pub fn model(&self) -> Result<RobotModel, RobotConfigError> {
        let mut model = load_urdf(&self.urdf, self.tool_link.as_deref())?;
        let tool = self.tool_offset.iter().chain(&self.tool_rpy);
        if !tool.clone().all(|v| v.is_finite()) {
            return Err(RobotConfigError::NonFiniteTool);
        }
        // A zero mount leaves the URDF's flange numbers exactly as loaded.
        if tool.clone().any(|&v| v != 0.0) {
            mount_tool(&mut model, self.tool_offset, self.tool_rpy);
        }
        if let Some(home) = &self.home {
            if home.len() != model.dof() {
                return Err(RobotConfigError::HomeLength {
                    dof: model.dof(),
                    model: model.name,
                    got: home.len(),
                });
            }
            for (joint, &value) in model.joints.iter().zip(home) {
                if !(joint.lower..=joint.upper).contains(&value) {
                    return Err(RobotConfigError::HomeOutOfRange {
                        joint: joint.name.clone(),
                        value,
                        lower: joint.lower,
                        upper: joint.upper,
                    });
                }
            }
            model.home = home.clone();
        }
        Ok(model)
    }
}

/// Move `model`'s flange to the frame `(xyz, rpy)` given in the flange frame.
fn mount_tool(model: &mut RobotModel, xyz: [f64; 3], rpy: [f64; 3]) {
    let euler = |r: [f64; 3]| Rotation3::from_euler_angles(r[0], r[1], r[2]);
    let flange = euler(model.flange_rpy);
    let position = Vector3::from(model.flange_xyz) + flange * Vector3::from(xyz);
    let (roll, pitch, yaw) = (flange * euler(rpy)).euler_angles();
    model.flange_xyz = position.into();
    model.flange_rpy = [roll, pitch, yaw];
}

/// A name picks a built-in arm, a table a URDF; each form reports its own mistakes
/// (unknown name, unknown key) instead of serde's "did not match any variant".
impl<'de> Deserialize<'de> for RobotConfig {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Form;
        impl<'de> Visitor<'de> for Form {
            type Value = RobotConfig;

            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(
                    "a built-in arm (\"panda\", \"ur5e\") or a table {urdf = \"path\", ...}",
                )
            }

            fn visit_str<E: de::Error>(self, name: &str) -> Result<RobotConfig, E> {
                RobotKind::deserialize(name.into_deserializer()).map(RobotConfig::Builtin)
            }

            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<RobotConfig, A::Error> {
                UrdfRobot::deserialize(de::value::MapAccessDeserializer::new(map))
                    .map(RobotConfig::Urdf)
            }
        }
        deserializer.deserialize_any(Form)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A temporary folder holding the test arm (three revolute joints, a trailing `tool0`
    /// 0.2 m along link3's x with its z axis along that x) and a file that is not URDF.
    struct Files {
        dir: PathBuf,
    }

    impl Files {
        fn new(name: &str) -> Self {
            let dir = std::env::temp_dir().join(format!("echogym-{name}-{}", std::process::id()));
            std::fs::create_dir_all(&dir).unwrap();
            let arm = include_str!("../../../../tests/data/three_link_arm.urdf");
            std::fs::write(dir.join("arm.urdf"), arm).unwrap();
            std::fs::write(dir.join("broken.urdf"), "<robot name=\"x\"><link").unwrap();
            Self { dir }
        }

        fn robot(&self, file: &str) -> UrdfRobot {
            UrdfRobot::new(self.dir.join(file))
        }
    }

    impl Drop for Files {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }

    #[test]
    fn configs_name_a_built_in_arm_or_a_urdf_table() {
        let parse = |v: serde_json::Value| serde_json::from_value::<RobotConfig>(v);
        assert_eq!(
            parse(serde_json::json!("ur5e")).unwrap(),
            RobotConfig::Builtin(RobotKind::Ur5e)
        );
        let table = parse(serde_json::json!({"urdf": "/a.urdf", "tool_offset": [0, 0, 0.05]}));
        let expected = UrdfRobot {
            tool_offset: [0.0, 0.0, 0.05],
            ..UrdfRobot::new("/a.urdf")
        };
        assert_eq!(table.unwrap(), RobotConfig::Urdf(expected.clone()));
        // Serialized back the same way.
        let back = serde_json::to_value(RobotConfig::Urdf(expected.clone())).unwrap();
        assert_eq!(parse(back).unwrap(), RobotConfig::Urdf(expected));
        assert_eq!(
            serde_json::to_value(RobotConfig::default()).unwrap(),
            serde_json::json!("panda")
        );

        let unknown = parse(serde_json::json!("ur10")).unwrap_err().to_string();
        assert!(
            unknown.contains("ur10") && unknown.contains("ur5e"),
            "{unknown}"
        );
        let typo = parse(serde_json::json!({"urdf": "/a.urdf", "tool_ofset": [0, 0, 0]}));
        assert!(typo.unwrap_err().to_string().contains("tool_ofset"));
        assert!(parse(serde_json::json!({"tool_offset": [0, 0, 0]})).is_err());
        assert!(parse(serde_json::json!(3)).is_err());

        #[derive(Deserialize)]
        struct Scene {
            robot: RobotConfig,
        }
        let toml: Scene =
            toml::from_str("robot = {urdf = \"/a.urdf\", home = [0.0, 0.5, 1.0]}").unwrap();
        let RobotConfig::Urdf(robot) = toml.robot else {
            panic!("a table is a URDF arm");
        };
        assert_eq!(robot.home, Some(vec![0.0, 0.5, 1.0]));
    }

    #[test]
    fn urdf_arms_take_the_tool_mount_and_home_pose() {
        let files = Files::new("robot-config");
        let plain = RobotConfig::Urdf(files.robot("arm.urdf")).model().unwrap();
        assert_eq!(plain.dof(), 3);
        assert_eq!(plain.flange_xyz, [0.2, 0.0, 0.0]);

        // tool0's z is link3's x: a 5 cm mount along the tool axis ends 0.25 m along x.
        let mounted = UrdfRobot {
            tool_offset: [0.0, 0.0, 0.05],
            tool_rpy: [0.0, 0.0, 0.3],
            home: Some(vec![0.1, -0.2, 1.0]),
            ..files.robot("arm.urdf")
        }
        .model()
        .unwrap();
        let [x, y, z] = mounted.flange_xyz;
        assert!((x - 0.25).abs() < 1e-7 && y.abs() < 1e-12 && z.abs() < 1e-7);
        let [roll, pitch, yaw] = mounted.flange_rpy;
        let turned = Rotation3::from_euler_angles(roll, pitch, yaw);
        let [r0, p0, y0] = plain.flange_rpy;
        let expected =
            Rotation3::from_euler_angles(r0, p0, y0) * Rotation3::from_euler_angles(0.0, 0.0, 0.3);
        assert!(turned.angle_to(&expected) < 1e-12);
        assert_eq!(mounted.home, [0.1, -0.2, 1.0]);
        assert_eq!(mounted.joints, plain.joints);
    }

    #[test]
    fn bad_urdf_arms_are_typed_errors() {
        let files = Files::new("robot-config-errors");
        let err = |robot: UrdfRobot| RobotConfig::Urdf(robot).model().unwrap_err();

        let missing = err(files.robot("missing.urdf"));
        assert!(matches!(
            missing,
            RobotConfigError::Urdf(UrdfError::Read { .. })
        ));
        assert!(missing.to_string().contains("missing.urdf"), "{missing}");
        let broken = err(files.robot("broken.urdf"));
        assert!(matches!(
            broken,
            RobotConfigError::Urdf(UrdfError::Read { .. })
        ));
        let tool = err(UrdfRobot {
            tool_link: Some("gripper".into()),
            ..files.robot("arm.urdf")
        });
        assert!(matches!(
            tool,
            RobotConfigError::Urdf(UrdfError::UnknownToolLink { .. })
        ));
        let short = err(UrdfRobot {
            home: Some(vec![0.0, 0.0]),
            ..files.robot("arm.urdf")
        });
        assert_eq!(
            short.to_string(),
            "home has 2 values for the 3 joints of three_link_arm"
        );
        // elbow: [0.2, 2.5] rad.
        let outside = err(UrdfRobot {
            home: Some(vec![0.0, 0.0, 0.0]),
            ..files.robot("arm.urdf")
        });
        assert!(
            matches!(outside, RobotConfigError::HomeOutOfRange { ref joint, .. } if joint == "elbow")
        );
        let nan = err(UrdfRobot {
            tool_offset: [f64::NAN, 0.0, 0.0],
            ..files.robot("arm.urdf")
        });
        assert_eq!(nan, RobotConfigError::NonFiniteTool);
    }
}
