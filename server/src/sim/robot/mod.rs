//! Robot arms: models (built-in URDFs, user URDFs) and their rapier multibodies.

mod arm;
mod builtin;
mod config;
mod model;
mod urdf;

pub use arm::{Arm, ArmError, rpy_rotation};
pub use builtin::RobotKind;
pub use config::{RobotConfig, RobotConfigError, UrdfRobot};
pub use model::{Capsule, JointSpec, LinkSpec, RobotModel};
pub use urdf::{UrdfError, load_urdf, load_urdf_str};
