//! Controllers turning actions into joint torques: robosuite's set (OSC_POSE, joint
//! position, joint velocity; joint torque is `Scene::step` itself) and the seed thesis's
//! hybrid force/motion controller.

mod arm_controller;
mod config;
mod hybrid;
mod joint;
mod osc;

pub use arm_controller::ArmController;
pub use config::{ControllerConfig, ControllerConfigError, ControllerKind, ImpedanceMode};
pub use hybrid::{ForceGains, HybridForceMotion};
pub use joint::{JointPosition, JointVelocity};
pub use osc::{Osc, OscParams};
