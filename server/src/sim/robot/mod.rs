//! Robot arms: models (UR5e, Panda, URDF) and their rapier multibodies.

mod arm;
mod model;
mod panda;
mod ur5e;
mod urdf;

pub use arm::{Arm, ArmError, rpy_rotation};
pub use model::{Capsule, JointSpec, LinkSpec, RobotModel};
pub use panda::panda;
pub use ur5e::ur5e;
pub use urdf::{UrdfError, load_urdf, load_urdf_str};
