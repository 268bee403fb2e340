//! Loading any serial arm from URDF into a [`RobotModel`].
//!
//! Parsed with `urdf-rs` (the parser `rapier3d-urdf` is built on); the chain is then
//! built by our own [`super::Arm`] so that user robots get exactly the actuation,
//! dynamics and controllers of the built-in ones. Fixed joints are merged: their child
//! link's mass joins the moving link before them (parallel-axis theorem), and trailing
//! fixed joints (`flange`, `tool0`) become the flange frame. Collision geometry becomes
//! capsules (cylinders and capsules exactly; boxes along their longest side; spheres as
//! zero-length capsules); meshes are skipped. URDF carries no home pose: each joint starts
//! at 0, or at the middle of its range when 0 is outside it.

use std::path::Path;

use rapier3d::na::{Matrix3, Rotation3, Vector3};

use super::model::{Capsule, JointSpec, LinkSpec, RobotModel};

/// A URDF could not be turned into a serial arm.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UrdfError {
    /// The file could not be read or parsed.
    #[error("cannot read URDF {path}: {message}")]
    Read {
        /// The file (or `<string>`).
        path: String,
        /// What the parser said.
        message: String,
    },
    /// A link has several moving children: not a serial chain.
    #[error("URDF link {link} branches into several joints; echogym loads serial arms only")]
    NotSerial {
        /// The branching link.
        link: String,
    },
    /// A joint type other than revolute, continuous or fixed.
    #[error(
        "URDF joint {joint} is {kind}; echogym arms support revolute, continuous and fixed joints"
    )]
    UnsupportedJoint {
        /// The joint.
        joint: String,
        /// Its type.
        kind: String,
    },
    /// No moving joint, or no root link.
    #[error("URDF {robot} has no chain of revolute joints from a root link")]
    NoChain {
        /// The robot name.
        robot: String,
    },
}

/// A rigid transform.
#[derive(Clone, Copy)]
struct Transform {
    rotation: Rotation3<f64>,
    translation: Vector3<f64>,
}

impl Transform {
    fn identity() -> Self {
        Self {
            rotation: Rotation3::identity(),
            translation: Vector3::zeros(),
        }
    }

    fn from_pose(pose: &urdf_rs::Pose) -> Self {
        Self {
            rotation: Rotation3::from_euler_angles(pose.rpy[0], pose.rpy[1], pose.rpy[2]),
            translation: Vector3::from(pose.xyz.0),
        }
    }

    fn then(&self, next: &Self) -> Self {
        Self {
            rotation: self.rotation * next.rotation,
            translation: self.translation + self.rotation * next.translation,
        }
    }

    fn point(&self, p: Vector3<f64>) -> Vector3<f64> {
        self.rotation * p + self.translation
    }

    fn xyz(&self) -> [f64; 3] {
        self.translation.into()
    }

    fn rpy(&self) -> [f64; 3] {
        let (r, p, y) = self.rotation.euler_angles();
        [r, p, y]
    }
}

/// Mass properties being accumulated for one moving link, in its frame.
struct Body {
    mass: f64,
    com: Vector3<f64>,
    inertia: Matrix3<f64>,
    capsules: Vec<Capsule>,
}

impl Body {
    fn empty() -> Self {
        Self {
            mass: 0.0,
            com: Vector3::zeros(),
            inertia: Matrix3::zeros(),
            capsules: Vec::new(),
        }
    }

    /// Add `link`, whose frame is `at` in this body's frame.
    fn absorb(&mut self, link: &urdf_rs::Link, at: &Transform) {
        let inertial = at.then(&Transform::from_pose(&link.inertial.origin));
        let m2 = link.inertial.mass.value;
        let i = &link.inertial.inertia;
        let local = Matrix3::new(
            i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz,
        );
        let r = inertial.rotation.matrix();
        let i2 = r * local * r.transpose();
        let c2 = inertial.translation;
        let total = self.mass + m2;
        if total > 0.0 {
            let com = (self.com * self.mass + c2 * m2) / total;
            let shift =
                |m: f64, d: Vector3<f64>| (Matrix3::identity() * d.dot(&d) - d * d.transpose()) * m;
            self.inertia =
                self.inertia + shift(self.mass, self.com - com) + i2 + shift(m2, c2 - com);
            self.com = com;
            self.mass = total;
        }
        for collision in &link.collision {
            let frame = at.then(&Transform::from_pose(&collision.origin));
            if let Some((a, b, radius)) = capsule_of(&collision.geometry) {
                self.capsules.push(Capsule {
                    a: frame.point(a).into(),
                    b: frame.point(b).into(),
                    radius,
                });
            }
        }
    }

    fn spec(&self, name: &str) -> LinkSpec {
        let i = &self.inertia;
        LinkSpec {
            name: name.to_owned(),
            mass: self.mass,
            com: self.com.into(),
            inertia: [
                i[(0, 0)],
                i[(1, 1)],
                i[(2, 2)],
                i[(0, 1)],
                i[(0, 2)],
                i[(1, 2)],
            ],
            capsules: self.capsules.clone(),
        }
    }
}

/// A capsule `(a, b, radius)` approximating a collision geometry, in its own frame.
fn capsule_of(geometry: &urdf_rs::Geometry) -> Option<(Vector3<f64>, Vector3<f64>, f64)> {
    use urdf_rs::Geometry;
    match geometry {
        Geometry::Cylinder { radius, length } | Geometry::Capsule { radius, length } => {
            let half = Vector3::new(0.0, 0.0, length / 2.0);
            Some((-half, half, *radius))
        }
        Geometry::Sphere { radius } => Some((Vector3::zeros(), Vector3::zeros(), *radius)),
        Geometry::Box { size } => {
            let half = Vector3::from(size.0) / 2.0;
            let long = half.imax();
            let radius = (0..3)
                .filter(|&k| k != long)
                .map(|k| half[k])
                .fold(0.0, f64::max);
            let mut axis = Vector3::zeros();
            axis[long] = (half[long] - radius).max(0.0);
            Some((-axis, axis, radius))
        }
        _ => None,
    }
}

/// Load a serial arm from a URDF file.
pub fn load_urdf(path: &Path) -> Result<RobotModel, UrdfError> {
    let robot = urdf_rs::read_file(path).map_err(|e| UrdfError::Read {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    model_from_urdf(&robot)
}

/// Load a serial arm from URDF text.
pub fn load_urdf_str(text: &str) -> Result<RobotModel, UrdfError> {
    let robot = urdf_rs::read_from_string(text).map_err(|e| UrdfError::Read {
        path: "<string>".into(),
        message: e.to_string(),
    })?;
    model_from_urdf(&robot)
}

fn model_from_urdf(robot: &urdf_rs::Robot) -> Result<RobotModel, UrdfError> {
    let no_chain = || UrdfError::NoChain {
        robot: robot.name.clone(),
    };
    let link = |name: &str| robot.links.iter().find(|l| l.name == name);
    let root = robot
        .links
        .iter()
        .find(|l| !robot.joints.iter().any(|j| j.child.link == l.name))
        .ok_or_else(no_chain)?;

    let mut base = Body::empty();
    base.absorb(root, &Transform::identity());
    let mut current = base;
    let mut current_name = root.name.clone();
    let mut pending = Transform::identity();
    let mut joints: Vec<JointSpec> = Vec::new();
    let mut base_spec = None;
    let mut at = root.name.clone();
    loop {
        let children: Vec<&urdf_rs::Joint> = robot
            .joints
            .iter()
            .filter(|j| j.parent.link == at)
            .collect();
        let joint = match children.as_slice() {
            [] => break,
            [one] => *one,
            _ => return Err(UrdfError::NotSerial { link: at }),
        };
        let child = link(&joint.child.link).ok_or_else(no_chain)?;
        let origin = pending.then(&Transform::from_pose(&joint.origin));
        match joint.joint_type {
            urdf_rs::JointType::Fixed => {
                current.absorb(child, &origin);
                pending = origin;
            }
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                let finished = current.spec(&current_name);
                if joints.is_empty() {
                    base_spec = Some(finished);
                } else {
                    joints.last_mut().expect("non-empty").link = finished;
                }
                let continuous = matches!(joint.joint_type, urdf_rs::JointType::Continuous)
                    || !joint.limit.lower.is_finite();
                let (lower, upper) = if continuous {
                    (-1e3, 1e3)
                } else {
                    (joint.limit.lower, joint.limit.upper)
                };
                let dynamics = joint.dynamics.as_ref();
                joints.push(JointSpec {
                    name: joint.name.clone(),
                    origin_xyz: origin.xyz(),
                    origin_rpy: origin.rpy(),
                    axis: joint.axis.xyz.0,
                    lower,
                    upper,
                    max_velocity: joint.limit.velocity,
                    max_effort: if joint.limit.effort > 0.0 {
                        joint.limit.effort
                    } else {
                        f64::INFINITY
                    },
                    damping: dynamics.map_or(0.0, |d| d.damping),
                    friction: dynamics.map_or(0.0, |d| d.friction),
                    link: LinkSpec {
                        name: String::new(),
                        mass: 0.0,
                        com: [0.0; 3],
                        inertia: [0.0; 6],
                        capsules: Vec::new(),
                    },
                });
                current = Body::empty();
                current.absorb(child, &Transform::identity());
                current_name = child.name.clone();
                pending = Transform::identity();
            }
            ref other => {
                return Err(UrdfError::UnsupportedJoint {
                    joint: joint.name.clone(),
                    kind: format!("{other:?}").to_lowercase(),
                });
            }
        }
        at = child.name.clone();
    }
    let last = joints.last_mut().ok_or_else(no_chain)?;
    last.link = current.spec(&current_name);
    let home = joints
        .iter()
        .map(|j| {
            if (j.lower..=j.upper).contains(&0.0) {
                0.0
            } else {
                (j.lower + j.upper) / 2.0
            }
        })
        .collect();
    Ok(RobotModel {
        name: robot.name.clone(),
        base: base_spec.expect("set at the first moving joint"),
        joints,
        flange_xyz: pending.xyz(),
        flange_rpy: pending.rpy(),
        home,
    })
}
