//! [`RobotModel`]: a serial arm described like a URDF (joint origins, axes, limits,
//! link inertials, simple collision capsules), as the URDF loader builds it for the
//! built-in arms and for users' files.
//!
//! Units: metres, radians, kilograms, kg·m², seconds, newtons, newton-metres.
//! Frames: every joint origin is given in the frame of its parent link (URDF
//! convention: translation `xyz`, then fixed-axis roll-pitch-yaw `rpy`); a joint rotates
//! its child link about `axis`, expressed in the joint frame; the child link frame is the
//! joint frame. Inertials are about the link's centre of mass, in the link frame.

use serde::{Deserialize, Serialize};

/// A capsule collision shape between two points of a link frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Capsule {
    /// First segment end, link frame \[m\].
    pub a: [f64; 3],
    /// Second segment end, link frame \[m\].
    pub b: [f64; 3],
    /// Radius \[m\].
    pub radius: f64,
}

/// Mass properties and collision shapes of one link.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinkSpec {
    /// Link name (URDF `link name`).
    pub name: String,
    /// Mass \[kg\].
    pub mass: f64,
    /// Centre of mass in the link frame \[m\].
    pub com: [f64; 3],
    /// Inertia about the centre of mass, link-frame axes [kg·m²]:
    /// `[ixx, iyy, izz, ixy, ixz, iyz]`.
    pub inertia: [f64; 6],
    /// Collision capsules (may be empty).
    pub capsules: Vec<Capsule>,
}

/// A revolute joint and the link it moves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointSpec {
    /// Joint name.
    pub name: String,
    /// Joint frame origin in the parent link frame \[m\].
    pub origin_xyz: [f64; 3],
    /// Joint frame orientation in the parent link frame, fixed-axis roll-pitch-yaw \[rad\].
    pub origin_rpy: [f64; 3],
    /// Rotation axis in the joint frame (unit vector).
    pub axis: [f64; 3],
    /// Lower position limit \[rad\].
    pub lower: f64,
    /// Upper position limit \[rad\].
    pub upper: f64,
    /// Velocity limit [rad/s].
    pub max_velocity: f64,
    /// Torque limit [N·m].
    pub max_effort: f64,
    /// Viscous joint damping [N·m·s/rad].
    pub damping: f64,
    /// Coulomb joint friction [N·m].
    pub friction: f64,
    /// The link this joint moves.
    pub link: LinkSpec,
}

/// A fixed-base serial arm.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotModel {
    /// Model name, e.g. `"ur5e"`.
    pub name: String,
    /// The base link (fixed to the world at the robot's mounting pose).
    pub base: LinkSpec,
    /// Joints from base to flange.
    pub joints: Vec<JointSpec>,
    /// Tool flange frame in the last link frame: translation \[m\].
    pub flange_xyz: [f64; 3],
    /// Tool flange frame in the last link frame: roll-pitch-yaw \[rad\].
    pub flange_rpy: [f64; 3],
    /// A comfortable starting configuration \[rad\], one per joint.
    pub home: Vec<f64>,
}

impl RobotModel {
    /// Number of joints (degrees of freedom).
    pub fn dof(&self) -> usize {
        self.joints.len()
    }
}
