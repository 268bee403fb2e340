//! Loading any serial arm from URDF into a [`RobotModel`].
//!
//! Parsed with `urdf-rs` (the parser `rapier3d-urdf` is built on); the chain is then
//! built by our own [`super::Arm`] so that user robots get exactly the actuation,
//! dynamics and controllers of the built-in ones.
//!
//! The arm is the path of joints from the root link to the tool link: the one named, or
//! else the leaf reached through the most moving joints (the deepest on a tie). Fixed
//! joints are merged: their child link's mass joins the moving link before them
//! (parallel-axis theorem); links hanging off the path through fixed joints only (UR's
//! `base`, sensor or camera frames) join the same way; trailing fixed joints on the path
//! (`flange`, `tool0`) become the flange frame. A frame made of one joint origin is kept
//! exactly as written; composed frames drop round-off below 1e-12 m or rad, so frames that
//! cancel (UR's `flange` → `tool0`) are exactly the identity. Collision geometry becomes
//! capsules (capsules and cylinders exactly; boxes along their longest side; spheres as
//! zero-length capsules); meshes are skipped. URDF carries no home pose: each joint starts
//! at 0, or at the middle of its range when 0 is outside it.

use std::path::Path;

use rapier3d::na::{Matrix3, Rotation3, Vector3};

use super::model::{Capsule, JointSpec, LinkSpec, RobotModel};

/// Components of composed frames below this are round-off and set to 0 [m, rad].
const ROUND_OFF: f64 = 1e-12;

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
    /// A moving joint leaves the path from the root to the tool link: not a serial chain.
    #[error("URDF link {link} branches into several moving joints; echogym loads serial arms only")]
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
    /// A joint names a link the file does not define, or a link has several parents.
    #[error("URDF link {link} is missing or has several parent joints")]
    NotATree {
        /// The link.
        link: String,
    },
    /// The requested tool link is not in the file.
    #[error("URDF {robot} has no link {link} to use as the tool link")]
    UnknownToolLink {
        /// The robot name.
        robot: String,
        /// The requested link.
        link: String,
    },
    /// Several leaves could be the tool link.
    #[error("URDF {robot} ends in several equally long chains ({leaves}); name the tool link")]
    AmbiguousToolLink {
        /// The robot name.
        robot: String,
        /// The candidate leaves, comma-separated.
        leaves: String,
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
}

/// The frame of a sequence of joint origins, as URDF `(xyz, rpy)`: one origin verbatim,
/// several composed with round-off dropped.
fn frame_of(origins: &[&urdf_rs::Pose]) -> ([f64; 3], [f64; 3]) {
    match origins {
        [] => ([0.0; 3], [0.0; 3]),
        [one] => (one.xyz.0, one.rpy.0),
        _ => {
            let t = compose(origins);
            let (r, p, y) = t.rotation.euler_angles();
            let clean = |v: f64| if v.abs() < ROUND_OFF { 0.0 } else { v };
            (t.translation.map(clean).into(), [r, p, y].map(clean))
        }
    }
}

fn compose(origins: &[&urdf_rs::Pose]) -> Transform {
    origins.iter().fold(Transform::identity(), |t, pose| {
        t.then(&Transform::from_pose(pose))
    })
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

    /// Add `link`, whose frame is `at` in this body's frame. The first massive link is
    /// taken as written and massless ones add only collisions, so a link merged with
    /// nothing keeps its numbers exactly.
    fn absorb(&mut self, link: &urdf_rs::Link, at: &Transform) {
        let m2 = link.inertial.mass.value;
        if m2 > 0.0 {
            let inertial = at.then(&Transform::from_pose(&link.inertial.origin));
            let i = &link.inertial.inertia;
            let local = Matrix3::new(
                i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz,
            );
            let r = inertial.rotation.matrix();
            let i2 = r * local * r.transpose();
            let c2 = inertial.translation;
            if self.mass > 0.0 {
                let total = self.mass + m2;
                let com = (self.com * self.mass + c2 * m2) / total;
                let shift = |m: f64, d: Vector3<f64>| {
                    (Matrix3::identity() * d.dot(&d) - d * d.transpose()) * m
                };
                self.inertia =
                    self.inertia + shift(self.mass, self.com - com) + i2 + shift(m2, c2 - com);
                self.com = com;
                self.mass = total;
            } else {
                self.inertia = i2;
                self.com = c2;
                self.mass = m2;
            }
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

/// A capsule `(a, b, radius)` approximating a collision geometry, in its own frame: the
/// segment runs along +z for capsules and cylinders.
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

/// Load a serial arm from a URDF file. `tool_link`: the link whose frame is the flange
/// (default: see the module documentation).
pub fn load_urdf(path: &Path, tool_link: Option<&str>) -> Result<RobotModel, UrdfError> {
    let robot = urdf_rs::read_file(path).map_err(|e| UrdfError::Read {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    model_from_urdf(&robot, tool_link)
}

/// Load a serial arm from URDF text (see [`load_urdf`]).
pub fn load_urdf_str(text: &str, tool_link: Option<&str>) -> Result<RobotModel, UrdfError> {
    let robot = urdf_rs::read_from_string(text).map_err(|e| UrdfError::Read {
        path: "<string>".into(),
        message: e.to_string(),
    })?;
    model_from_urdf(&robot, tool_link)
}

/// The link tree of a URDF.
struct Tree<'a> {
    robot: &'a urdf_rs::Robot,
}

impl<'a> Tree<'a> {
    /// Check that every joint joins links the file defines.
    fn new(robot: &'a urdf_rs::Robot) -> Result<Self, UrdfError> {
        let tree = Self { robot };
        for joint in &robot.joints {
            tree.link(&joint.parent.link)?;
            tree.link(&joint.child.link)?;
        }
        Ok(tree)
    }

    fn link(&self, name: &str) -> Result<&'a urdf_rs::Link, UrdfError> {
        self.robot
            .links
            .iter()
            .find(|l| l.name == name)
            .ok_or_else(|| UrdfError::NotATree { link: name.into() })
    }

    fn children(&self, link: &str) -> impl Iterator<Item = &'a urdf_rs::Joint> {
        self.robot
            .joints
            .iter()
            .filter(move |j| j.parent.link == link)
    }

    /// The joint whose child is `link` (none for the root).
    fn parent(&self, link: &str) -> Result<Option<&'a urdf_rs::Joint>, UrdfError> {
        let mut parents = self.robot.joints.iter().filter(|j| j.child.link == link);
        match (parents.next(), parents.next()) {
            (one, None) => Ok(one),
            _ => Err(UrdfError::NotATree { link: link.into() }),
        }
    }

    /// Joints from the root to `link`, in order.
    fn path_to(&self, link: &str) -> Result<Vec<&'a urdf_rs::Joint>, UrdfError> {
        let mut path = Vec::new();
        let mut at = link;
        while let Some(joint) = self.parent(at)? {
            if path.len() > self.robot.joints.len() {
                return Err(UrdfError::NotATree { link: link.into() });
            }
            path.push(joint);
            at = &joint.parent.link;
        }
        path.reverse();
        Ok(path)
    }

    fn tool_link(&self, requested: Option<&str>) -> Result<&'a str, UrdfError> {
        if let Some(name) = requested {
            return self
                .robot
                .links
                .iter()
                .find(|l| l.name == name)
                .map(|l| l.name.as_str())
                .ok_or_else(|| UrdfError::UnknownToolLink {
                    robot: self.robot.name.clone(),
                    link: name.into(),
                });
        }
        let mut best: Vec<&'a str> = Vec::new();
        let mut best_score = (0, 0);
        for leaf in &self.robot.links {
            if self.children(&leaf.name).next().is_some() {
                continue;
            }
            let path = self.path_to(&leaf.name)?;
            let moving = path
                .iter()
                .filter(|j| !matches!(j.joint_type, urdf_rs::JointType::Fixed))
                .count();
            let score = (moving, path.len());
            if score > best_score {
                best_score = score;
                best.clear();
            }
            if score == best_score {
                best.push(&leaf.name);
            }
        }
        match best.as_slice() {
            [one] => Ok(one),
            [] => Err(UrdfError::NoChain {
                robot: self.robot.name.clone(),
            }),
            many => Err(UrdfError::AmbiguousToolLink {
                robot: self.robot.name.clone(),
                leaves: many.join(", "),
            }),
        }
    }

    /// Merge `link` (frame `at` in `body`'s frame) and every link hanging off it through
    /// fixed joints into `body`, except the subtree behind `next`, the path's next joint.
    fn absorb_branch(
        &self,
        body: &mut Body,
        link: &urdf_rs::Link,
        at: &Transform,
        next: Option<&urdf_rs::Joint>,
    ) -> Result<(), UrdfError> {
        body.absorb(link, at);
        for joint in self.children(&link.name) {
            if next.is_some_and(|n| std::ptr::eq(n, joint)) {
                continue;
            }
            if !matches!(joint.joint_type, urdf_rs::JointType::Fixed) {
                return Err(UrdfError::NotSerial {
                    link: link.name.clone(),
                });
            }
            let child = self.link(&joint.child.link)?;
            let frame = at.then(&Transform::from_pose(&joint.origin));
            self.absorb_branch(body, child, &frame, None)?;
        }
        Ok(())
    }
}

fn model_from_urdf(
    robot: &urdf_rs::Robot,
    tool_link: Option<&str>,
) -> Result<RobotModel, UrdfError> {
    let tree = Tree::new(robot)?;
    let tool = tree.tool_link(tool_link)?;
    let path = tree.path_to(tool)?;
    let root_name = path.first().map_or(tool, |j| j.parent.link.as_str());
    let root = tree.link(root_name)?;

    let mut current = Body::empty();
    tree.absorb_branch(
        &mut current,
        root,
        &Transform::identity(),
        path.first().copied(),
    )?;
    let mut current_name = root.name.clone();
    let mut base_spec = None;
    let mut pending: Vec<&urdf_rs::Pose> = Vec::new();
    let mut joints: Vec<JointSpec> = Vec::new();
    for (k, joint) in path.iter().enumerate() {
        let child = tree.link(&joint.child.link)?;
        let next = path.get(k + 1).copied();
        pending.push(&joint.origin);
        match joint.joint_type {
            urdf_rs::JointType::Fixed => {
                tree.absorb_branch(&mut current, child, &compose(&pending), next)?;
            }
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                let finished = current.spec(&current_name);
                match joints.last_mut() {
                    None => base_spec = Some(finished),
                    Some(last) => last.link = finished,
                }
                joints.push(joint_spec(joint, frame_of(&pending)));
                current = Body::empty();
                tree.absorb_branch(&mut current, child, &Transform::identity(), next)?;
                current_name = child.name.clone();
                pending.clear();
            }
            ref other => {
                return Err(UrdfError::UnsupportedJoint {
                    joint: joint.name.clone(),
                    kind: format!("{other:?}").to_lowercase(),
                });
            }
        }
    }
    let no_chain = || UrdfError::NoChain {
        robot: robot.name.clone(),
    };
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
    let (flange_xyz, flange_rpy) = frame_of(&pending);
    Ok(RobotModel {
        name: robot.name.clone(),
        base: base_spec.ok_or_else(no_chain)?,
        joints,
        flange_xyz,
        flange_rpy,
        home,
    })
}

/// A moving joint with origin `(xyz, rpy)` in its parent link; its link is filled in
/// once the next moving joint (or the tool) is reached.
fn joint_spec(joint: &urdf_rs::Joint, (origin_xyz, origin_rpy): ([f64; 3], [f64; 3])) -> JointSpec {
    let continuous = matches!(joint.joint_type, urdf_rs::JointType::Continuous)
        || !joint.limit.lower.is_finite();
    let (lower, upper) = if continuous {
        (-1e3, 1e3)
    } else {
        (joint.limit.lower, joint.limit.upper)
    };
    let dynamics = joint.dynamics.as_ref();
    JointSpec {
        name: joint.name.clone(),
        origin_xyz,
        origin_rpy,
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
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-joint arm whose link `arm` carries the extra `tail` text (joints and links).
    fn arm(tail: &str) -> String {
        format!(
            r#"<robot name="t">
              <link name="base"/>
              <joint name="j" type="revolute"><parent link="base"/><child link="arm"/>
                <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
              <link name="arm"><inertial><mass value="1"/>
                <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
              {tail}
            </robot>"#
        )
    }

    fn fixed(name: &str, parent: &str, x: f64, mass: f64) -> String {
        format!(
            r#"<joint name="{name}_joint" type="fixed"><parent link="{parent}"/>
                 <child link="{name}"/><origin xyz="{x} 0 0"/></joint>
               <link name="{name}"><inertial><mass value="{mass}"/>
                 <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>"#
        )
    }

    #[test]
    fn fixed_side_links_merge_and_the_tool_link_can_be_named() {
        // `camera` hangs off `arm`; the chain ends in flange -> tool0.
        let text = arm(&[
            fixed("camera", "arm", -0.1, 1.0),
            fixed("flange", "arm", 0.1, 0.0),
            fixed("tool0", "flange", 0.1, 0.0),
        ]
        .concat());
        let model = load_urdf_str(&text, None).unwrap();
        assert_eq!(model.joints[0].link.mass, 2.0);
        assert!((model.joints[0].link.com[0] + 0.05).abs() < 1e-15);
        assert_eq!(model.flange_xyz, [0.2, 0.0, 0.0]);
        let at_flange = load_urdf_str(&text, Some("flange")).unwrap();
        assert_eq!(at_flange.flange_xyz, [0.1, 0.0, 0.0]);
        let at_camera = load_urdf_str(&text, Some("camera")).unwrap();
        assert_eq!(at_camera.flange_xyz, [-0.1, 0.0, 0.0]);
        assert!(matches!(
            load_urdf_str(&text, Some("hand")),
            Err(UrdfError::UnknownToolLink { .. })
        ));
    }

    #[test]
    fn ambiguous_or_branching_arms_are_refused() {
        let twins = arm(&[
            fixed("left", "arm", 0.1, 0.0),
            fixed("right", "arm", -0.1, 0.0),
        ]
        .concat());
        assert_eq!(
            load_urdf_str(&twins, None).unwrap_err().to_string(),
            "URDF t ends in several equally long chains (left, right); name the tool link"
        );
        assert!(load_urdf_str(&twins, Some("left")).is_ok());
        let finger = r#"<joint name="f" type="revolute"><parent link="arm"/><child link="finger"/>
              <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
            <link name="finger"/>"#;
        let branching = arm(&[finger, &fixed("tool0", "arm", 0.1, 0.0)].concat());
        assert!(matches!(
            load_urdf_str(&branching, Some("tool0")),
            Err(UrdfError::NotSerial { ref link }) if link == "arm"
        ));
        let orphan = arm(
            r#"<joint name="x" type="fixed"><parent link="arm"/><child link="ghost"/></joint>"#,
        );
        assert!(matches!(
            load_urdf_str(&orphan, None),
            Err(UrdfError::NotATree { ref link }) if link == "ghost"
        ));
    }
}
