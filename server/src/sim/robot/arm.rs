//! [`Arm`]: a [`RobotModel`] built as a rapier multibody (reduced coordinates) with joint
//! torque actuation and the dynamics controllers need.
//!
//! rapier has no generalized-force setter: a joint torque τ is applied as `+τ·axis` on the
//! child link and `-τ·axis` on the parent link (user forces persist, so they are reset
//! before every step). rapier exposes each link's Jacobian but no mass matrix, so
//! `M(q) = Σ Jᵢᵀ·diag(mᵢ·I₃, Iᵢ)·Jᵢ` is assembled from the link Jacobians (rows
//! `[linear; angular]`, linear part at the link's centre of mass, world frame).
//! Joint damping (viscous, rapier's implicit per-DoF multibody damping) and Coulomb
//! friction (a velocity motor with target 0 capped at the friction torque) come from
//! the model; both are solved implicitly by rapier.

use rapier3d::glamx::EulerRot;
use rapier3d::na::{DMatrix, DVector, Matrix3, Matrix6xX, Vector3};
use rapier3d::prelude::*;

use super::model::{JointSpec, RobotModel};
use crate::sim::world::{World, arr3, groups, vec3};

/// Gain of the velocity motor that realises Coulomb joint friction [N·m·s/rad]: high, so
/// the joint sticks below the friction torque; rapier solves motors implicitly, so wrist
/// joints with 2e-4 kg·m² of inertia stay stable (an explicit friction torque did not).
const FRICTION_GAIN: f64 = 1e3;

/// Why an arm could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ArmError {
    /// The model has no joints or an invalid value.
    #[error("invalid robot model {model}: {message}")]
    InvalidModel {
        /// Model name.
        model: String,
        /// What is wrong.
        message: String,
    },
    /// rapier refused a joint (e.g. a cycle).
    #[error("rapier refused joint {joint} of {model}")]
    Joint {
        /// Model name.
        model: String,
        /// Joint name.
        joint: String,
    },
}

/// Rotation of URDF fixed-axis roll-pitch-yaw: `Rz(yaw)·Ry(pitch)·Rx(roll)`.
pub fn rpy_rotation(rpy: [f64; 3]) -> Rotation {
    Rotation::from_euler(
        EulerRot::ZYX,
        rpy[2] as Real,
        rpy[1] as Real,
        rpy[0] as Real,
    )
}

fn pose_of(xyz: [f64; 3], rpy: [f64; 3]) -> Pose {
    Pose::from_parts(vec3(xyz), rpy_rotation(rpy))
}

fn inertia_matrix(i: [f64; 6]) -> Matrix {
    let [ixx, iyy, izz, ixy, ixz, iyz] = i.map(|v| v as Real);
    Matrix::from_cols(
        Vector::new(ixx, ixy, ixz),
        Vector::new(ixy, iyy, iyz),
        Vector::new(ixz, iyz, izz),
    )
}

/// An arm in a [`World`].
#[derive(Debug, Clone)]
pub struct Arm {
    model: RobotModel,
    base: RigidBodyHandle,
    links: Vec<RigidBodyHandle>,
    link_ids: Vec<usize>,
    handle: MultibodyJointHandle,
    flange: Pose,
}

impl Arm {
    /// Build `model` with its base fixed at `base` (world pose) in its home
    /// configuration; `extra_last` adds colliders/mass to the last link (the tool).
    pub fn build(world: &mut World, model: RobotModel, base: Pose) -> Result<Self, ArmError> {
        let invalid = |message: String| ArmError::InvalidModel {
            model: model.name.clone(),
            message,
        };
        if model.joints.is_empty() {
            return Err(invalid("no joints".into()));
        }
        if model.home.len() != model.dof() {
            return Err(invalid(format!(
                "home has {} values for {} joints",
                model.home.len(),
                model.dof()
            )));
        }
        let s = &mut world.sets;
        let base_handle = s.bodies.insert(RigidBodyBuilder::fixed().pose(base));
        let robot_groups = InteractionGroups::new(
            groups::ROBOT,
            groups::TABLE | groups::OBJECT,
            InteractionTestMode::And,
        );
        let mut parent = base_handle;
        let mut parent_pose = base;
        let mut links = Vec::new();
        let mut last_handle = None;
        for (index, joint) in model.joints.iter().enumerate() {
            check_joint(joint).map_err(invalid)?;
            let origin = pose_of(joint.origin_xyz, joint.origin_rpy);
            let link_pose = parent_pose * origin;
            let link = &joint.link;
            let mprops = MassProperties::with_inertia_matrix(
                vec3(link.com),
                link.mass as Real,
                inertia_matrix(link.inertia),
            );
            let body = s.bodies.insert(
                RigidBodyBuilder::dynamic()
                    .pose(link_pose)
                    .additional_mass_properties(mprops)
                    .can_sleep(false),
            );
            // The base's neighbour links touch the table by construction: no colliders.
            if index >= 2 {
                for capsule in &link.capsules {
                    s.colliders.insert_with_parent(
                        ColliderBuilder::capsule_from_endpoints(
                            vec3(capsule.a),
                            vec3(capsule.b),
                            capsule.radius as Real,
                        )
                        .density(0.0)
                        .collision_groups(robot_groups),
                        body,
                        &mut s.bodies,
                    );
                }
            }
            let axis = vec3(joint.axis).normalize();
            let to_axis = Rotation::from_rotation_arc(Vector::X, axis);
            let data = GenericJointBuilder::new(JointAxesMask::LOCKED_REVOLUTE_AXES)
                .local_frame1(Pose::from_parts(
                    origin.translation,
                    origin.rotation * to_axis,
                ))
                .local_frame2(Pose::from_parts(Vector::ZERO, to_axis))
                .limits(JointAxis::AngX, [joint.lower as Real, joint.upper as Real])
                .motor_velocity(JointAxis::AngX, 0.0, FRICTION_GAIN as Real)
                .motor_max_force(JointAxis::AngX, joint.friction as Real)
                .contacts_enabled(false)
                .build();
            let handle = s
                .multibody_joints
                .insert(parent, body, data, true)
                .ok_or_else(|| ArmError::Joint {
                    model: model.name.clone(),
                    joint: joint.name.clone(),
                })?;
            last_handle = Some(handle);
            links.push(body);
            parent = body;
            parent_pose = link_pose;
        }
        for &h in &links {
            s.bodies[h].recompute_mass_properties_from_colliders(&s.colliders);
        }
        let handle = last_handle.expect("at least one joint");
        let link_ids: Vec<usize> = links
            .iter()
            .map(|&b| {
                s.multibody_joints
                    .rigid_body_link(b)
                    .map(|l| l.id)
                    .expect("link in multibody")
            })
            .collect();
        {
            let (mb, _) = s.multibody_joints.get_mut(handle).expect("just inserted");
            mb.set_self_contacts_enabled(false);
            let dofs: Vec<usize> = link_ids
                .iter()
                .map(|&id: &usize| mb.link(id).expect("link").assembly_id())
                .collect();
            let damping = mb.damping_mut();
            damping.fill(0.0);
            for (k, dof) in dofs.into_iter().enumerate() {
                damping[dof] = model.joints[k].damping as Real;
            }
        }
        let flange = pose_of(model.flange_xyz, model.flange_rpy);
        let arm = Self {
            base: base_handle,
            links,
            link_ids,
            handle,
            flange,
            model,
        };
        let home = arm.model.home.clone();
        arm.set_state(world, &home, &vec![0.0; home.len()]);
        Ok(arm)
    }

    /// The model.
    pub fn model(&self) -> &RobotModel {
        &self.model
    }

    /// Degrees of freedom.
    pub fn dof(&self) -> usize {
        self.links.len()
    }

    /// The last link's rigid body (the tool mounts on it).
    pub fn last_link(&self) -> RigidBodyHandle {
        *self.links.last().expect("non-empty")
    }

    /// Rigid bodies of the links, base excluded.
    pub fn links(&self) -> &[RigidBodyHandle] {
        &self.links
    }

    /// The flange frame in the last link's frame.
    pub fn flange_in_last_link(&self) -> Pose {
        self.flange
    }

    /// Joint positions \[rad\].
    pub fn q(&self, world: &World) -> Vec<f64> {
        let (mb, _) = world.sets.multibody_joints.get(self.handle).expect("arm");
        self.link_ids
            .iter()
            .map(|&id| mb.link(id).expect("link").joint().coords()[3] as f64)
            .collect()
    }

    /// Joint velocities [rad/s].
    pub fn qd(&self, world: &World) -> Vec<f64> {
        let (mb, _) = world.sets.multibody_joints.get(self.handle).expect("arm");
        self.link_ids
            .iter()
            .map(|&id| mb.joint_velocity(mb.link(id).expect("link"))[0] as f64)
            .collect()
    }

    /// Teleport to joint positions `q` \[rad\] and velocities `qd` [rad/s].
    pub fn set_state(&self, world: &mut World, q: &[f64], qd: &[f64]) {
        let s = &mut world.sets;
        let (mb, _) = s.multibody_joints.get_mut(self.handle).expect("arm");
        let mut disp: Vec<Real> = vec![0.0; mb.ndofs()];
        for (k, &id) in self.link_ids.iter().enumerate() {
            let link = mb.link(id).expect("link");
            disp[link.assembly_id()] = q[k] as Real - link.joint().coords()[3];
        }
        mb.apply_displacements(&disp);
        for (k, &id) in self.link_ids.iter().enumerate() {
            let dof = mb.link(id).expect("link").assembly_id();
            mb.generalized_velocity_mut()[dof] = qd[k] as Real;
        }
        mb.forward_kinematics(&s.bodies, true);
        mb.update_rigid_bodies(&mut s.bodies, true);
    }

    /// World pose of the flange.
    pub fn flange_pose(&self, world: &World) -> Pose {
        *world.sets.bodies[self.last_link()].position() * self.flange
    }

    /// World rotation axis of each joint.
    pub fn joint_axes(&self, world: &World) -> Vec<Vector> {
        let (mb, _) = world.sets.multibody_joints.get(self.handle).expect("arm");
        self.link_ids
            .iter()
            .enumerate()
            .map(|(k, &id)| {
                let link = mb.link(id).expect("link");
                let parent_pose = if k == 0 {
                    *world.sets.bodies[self.base].position()
                } else {
                    *world.sets.bodies[self.links[k - 1]].position()
                };
                (parent_pose.rotation * link.joint().data.local_frame1.rotation) * Vector::X
            })
            .collect()
    }

    /// Clear user forces and torques on every link (call before applying new ones).
    pub fn reset_forces(&self, world: &mut World) {
        for &h in &self.links {
            let body = &mut world.sets.bodies[h];
            body.reset_forces(false);
            body.reset_torques(false);
        }
    }

    /// Apply joint torques `tau` [N·m], clamped to the model's effort limits. Adds to
    /// forces already applied this step (joint damping and friction act inside rapier).
    pub fn apply_torques(&self, world: &mut World, tau: &[f64]) {
        let axes = self.joint_axes(world);
        for (k, joint) in self.model.joints.iter().enumerate() {
            let commanded = tau[k].clamp(-joint.max_effort, joint.max_effort);
            let torque = axes[k] * commanded as Real;
            world.sets.bodies[self.links[k]].add_torque(torque, true);
            let parent = if k == 0 { self.base } else { self.links[k - 1] };
            world.sets.bodies[parent].add_torque(-torque, true);
        }
    }

    /// Recompute forward kinematics and the link Jacobians for the current joint state;
    /// call once before [`Arm::point_jacobian`], [`Arm::mass_matrix`] and
    /// [`Arm::gravity_torques`] (they read the cached values).
    pub fn update_kinematics(&self, world: &mut World) {
        let s = &mut world.sets;
        let (mb, _) = s.multibody_joints.get_mut(self.handle).expect("arm");
        mb.forward_kinematics(&s.bodies, true);
    }

    /// Jacobian (6 × dof, rows `[linear; angular]`, world frame) of the point `point`
    /// [m, world] rigidly attached to the last link.
    pub fn point_jacobian(&self, world: &World, point: [f64; 3]) -> Matrix6xX<f64> {
        let (mb, _) = world.sets.multibody_joints.get(self.handle).expect("arm");
        let last = *self.link_ids.last().expect("links");
        let body_j = mb.body_jacobian(last);
        let com = world.sets.bodies[self.last_link()].center_of_mass();
        let r = Vector3::new(
            point[0] - com.x as f64,
            point[1] - com.y as f64,
            point[2] - com.z as f64,
        );
        let mut j = Matrix6xX::zeros(self.dof());
        for k in 0..self.dof() {
            let c = self.column(mb, body_j, k);
            let angular = Vector3::new(c[3], c[4], c[5]);
            let linear = Vector3::new(c[0], c[1], c[2]) + angular.cross(&r);
            j.fixed_view_mut::<3, 1>(0, k).copy_from(&linear);
            j.fixed_view_mut::<3, 1>(3, k).copy_from(&angular);
        }
        j
    }

    /// Column `k` (joint order) of a link's body Jacobian, which rapier stores in
    /// assembly order, in f64.
    fn column(&self, mb: &Multibody, body_j: &rapier3d::na::Matrix6xX<Real>, k: usize) -> [f64; 6] {
        let dof = mb.link(self.link_ids[k]).expect("link").assembly_id();
        std::array::from_fn(|row| body_j[(row, dof)] as f64)
    }

    /// Joint-space mass matrix `M(q)` (dof × dof), summed link by link with plain loops:
    /// the matrices are at most 7 × 7, where general matrix products cost more in
    /// call overhead than in arithmetic.
    pub fn mass_matrix(&self, world: &World) -> DMatrix<f64> {
        let (mb, _) = world.sets.multibody_joints.get(self.handle).expect("arm");
        let n = self.dof();
        let mut m = DMatrix::zeros(n, n);
        for (k, &id) in self.link_ids.iter().enumerate() {
            let body = &world.sets.bodies[self.links[k]];
            let props = &body.mass_properties().local_mprops;
            let mass = if props.inv_mass > 0.0 {
                1.0 / props.inv_mass as f64
            } else {
                0.0
            };
            let rot = Matrix::from_quat(body.position().rotation);
            let inertia = rot * props.reconstruct_inertia_matrix() * rot.transpose();
            let inertia = Matrix3::from_fn(|r, c| inertia.col(c)[r] as f64);
            let body_j = mb.body_jacobian(id);
            let columns: Vec<[f64; 6]> = (0..n).map(|a| self.column(mb, body_j, a)).collect();
            for (a, ca) in columns.iter().enumerate() {
                let iwa = inertia * Vector3::new(ca[3], ca[4], ca[5]);
                for (b, cb) in columns[..=a].iter().enumerate() {
                    let linear = ca[0] * cb[0] + ca[1] * cb[1] + ca[2] * cb[2];
                    let angular = iwa.x * cb[3] + iwa.y * cb[4] + iwa.z * cb[5];
                    m[(a, b)] += mass * linear + angular;
                }
            }
        }
        for a in 0..n {
            for b in 0..a {
                m[(b, a)] = m[(a, b)];
            }
        }
        m
    }

    /// Joint torques [N·m] that hold the arm (and its tool) against gravity `g`.
    pub fn gravity_torques(&self, world: &World) -> DVector<f64> {
        let g = world.gravity();
        let (mb, _) = world.sets.multibody_joints.get(self.handle).expect("arm");
        let mut tau = DVector::zeros(self.dof());
        for (k, &id) in self.link_ids.iter().enumerate() {
            let mass = world.sets.bodies[self.links[k]].mass() as f64;
            let body_j = mb.body_jacobian(id);
            for (c, t) in tau.iter_mut().enumerate() {
                let col = self.column(mb, body_j, c);
                *t -= mass * (col[0] * g[0] + col[1] * g[1] + col[2] * g[2]);
            }
        }
        tau
    }

    /// World centre of mass of link `k` \[m\].
    pub fn link_com(&self, world: &World, k: usize) -> [f64; 3] {
        arr3(world.sets.bodies[self.links[k]].center_of_mass())
    }
}

fn check_joint(joint: &JointSpec) -> Result<(), String> {
    let finite = joint
        .origin_xyz
        .iter()
        .chain(&joint.origin_rpy)
        .chain(&joint.axis)
        .all(|v| v.is_finite());
    let axis_len = joint.axis.iter().map(|a| a * a).sum::<f64>().sqrt();
    if !finite || axis_len < 1e-9 {
        return Err(format!(
            "joint {} has a non-finite origin or a zero axis",
            joint.name
        ));
    }
    if joint.lower.is_nan()
        || joint.lower > joint.upper
        || joint.max_effort < 0.0
        || joint.link.mass <= 0.0
    {
        return Err(format!(
            "joint {}: limits must be ordered, effort non-negative and link mass positive",
            joint.name
        ));
    }
    Ok(())
}
