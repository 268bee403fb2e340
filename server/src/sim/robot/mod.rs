//! Robot arms: models (built-in URDFs, user URDFs) and their rapier multibodies.

mod arm;
mod builtin;
mod model;
mod urdf;

pub use arm::{Arm, ArmError, rpy_rotation};
pub use builtin::RobotKind;
pub use model::{Capsule, JointSpec, LinkSpec, RobotModel};
pub use urdf::{ROUND_OFF, UrdfError, load_urdf, load_urdf_str};
