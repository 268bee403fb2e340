//! [`Osc`]: operational-space pose control of the probe tip (robosuite's `OSC_POSE`).
//!
//! `τ = Jᵀ·Λ·(Kp·e - Kd·ẋ) + g(q) + N·(Kp_null·(q_home - q) - Kd_null·q̇)` with the task-space
//! inertia `Λ = (J·M⁻¹·Jᵀ)⁻¹`, the tip Jacobian `J` (6 × dof, world frame), position and
//! orientation errors `e` (axis-angle), `Kd = 2·ζ·√Kp`, and the dynamically consistent
//! null-space projector `N = I - Jᵀ·J̄ᵀ`, `J̄ = M⁻¹·Jᵀ·Λ` (keeps redundant arms near home).

use rapier3d::na::{DMatrix, DVector};
use rapier3d::prelude::*;
use serde::{Deserialize, Serialize};

use crate::sim::scene::Scene;
use crate::sim::world::{arr3, vec3};

/// The OSC's pieces that other controllers reuse (the hybrid force/motion law).
pub(crate) struct TaskTerms {
    /// Desired task acceleration `Kp·e - Kd·ẋ` (linear, angular).
    pub task: DVector<f64>,
    /// Task-space inertia Λ.
    pub lambda: DMatrix<f64>,
    /// Tip Jacobian.
    pub j: DMatrix<f64>,
    /// Gravity torques [N·m].
    pub g: DVector<f64>,
}

/// Gains of the operational-space controller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OscParams {
    /// Stiffness per task axis `[x, y, z, rx, ry, rz]` [1/s²] (scaled by Λ). Default 150
    /// (robosuite's default).
    pub kp: [f64; 6],
    /// Damping ratio per task axis. Default 1 (critical).
    pub damping_ratio: [f64; 6],
    /// Null-space stiffness towards the home pose [1/s²]. Default 10.
    pub null_kp: f64,
    /// Add the model's Coulomb joint friction in the direction each joint is driven
    /// (smoothed over 5 % of the friction torque), as torque-controlled arms do.
    /// Default true: without it a Panda (0.2 N·m per joint) stops ≈ 8 mm short of a
    /// 5 cm goal at the default gains.
    pub friction_compensation: bool,
}

impl Default for OscParams {
    fn default() -> Self {
        Self {
            kp: [150.0; 6],
            damping_ratio: [1.0; 6],
            null_kp: 10.0,
            friction_compensation: true,
        }
    }
}

/// An operational-space controller holding a goal pose of the probe tip.
#[derive(Debug, Clone)]
pub struct Osc {
    /// Gains (may change per action in the variable-impedance modes).
    pub params: OscParams,
    goal_position: [f64; 3],
    goal_rotation: Rotation,
    home: Vec<f64>,
}

impl Osc {
    /// A controller whose goal is the tip's current pose.
    pub fn new(params: OscParams, scene: &Scene) -> Self {
        let tip = scene.tip_pose();
        Self {
            params,
            goal_position: arr3(tip.translation),
            goal_rotation: tip.rotation,
            home: scene.arm().model().home.clone(),
        }
    }

    /// The goal position \[m\] and rotation.
    pub fn goal(&self) -> ([f64; 3], Rotation) {
        (self.goal_position, self.goal_rotation)
    }

    /// Set the goal pose of the tip (world).
    pub fn set_goal(&mut self, position: [f64; 3], rotation: Rotation) {
        self.goal_position = position;
        self.goal_rotation = rotation;
    }

    /// Set the goal to the current tip pose moved by `delta` (`[dx, dy, dz]` in m and an
    /// axis-angle `[rx, ry, rz]` in rad, world frame).
    pub fn set_goal_delta(&mut self, scene: &Scene, delta: [f64; 6]) {
        let tip = scene.tip_pose();
        let p = arr3(tip.translation);
        self.goal_position = [p[0] + delta[0], p[1] + delta[1], p[2] + delta[2]];
        let rot = Rotation::from_scaled_axis(vec3([delta[3], delta[4], delta[5]]));
        self.goal_rotation = (rot * tip.rotation).normalize();
    }

    /// The pieces of the law at the current state.
    fn terms(&self, scene: &mut Scene) -> Terms {
        let tip = scene.tip_pose();
        let tip_p = arr3(tip.translation);
        let (arm, world) = scene.arm_kinematics();
        let j = arm.point_jacobian(world, tip_p);
        let m = arm.mass_matrix(world);
        let g = arm.gravity_torques(world);
        let q = DVector::from_vec(arm.q(world));
        let qd = DVector::from_vec(arm.qd(world));
        let n = q.len();
        let m_inv = m
            .clone()
            .try_inverse()
            .unwrap_or_else(|| DMatrix::identity(n, n));
        let lambda = pseudo_inverse(&(&j * &m_inv * j.transpose()));
        let mut e = DVector::zeros(6);
        for k in 0..3 {
            e[k] = self.goal_position[k] - tip_p[k];
        }
        let rot_err = (self.goal_rotation * tip.rotation.inverse()).to_scaled_axis();
        e[3] = rot_err.x as f64;
        e[4] = rot_err.y as f64;
        e[5] = rot_err.z as f64;
        let v = &j * &qd;
        let task = DVector::from_iterator(
            6,
            (0..6).map(|k| {
                let kp = self.params.kp[k];
                let kd = 2.0 * self.params.damping_ratio[k] * kp.sqrt();
                kp * e[k] - kd * v[k]
            }),
        );
        Terms {
            j,
            m,
            m_inv,
            lambda,
            g,
            q,
            qd,
            task,
        }
    }

    /// Desired task acceleration `Kp·e - Kd·ẋ`, task inertia Λ, tip Jacobian and gravity
    /// torques (for controllers that reuse the OSC's motion law).
    pub(crate) fn task_terms(&self, scene: &mut Scene) -> TaskTerms {
        let t = self.terms(scene);
        TaskTerms {
            task: t.task,
            lambda: t.lambda,
            j: t.j,
            g: t.g,
        }
    }

    /// Joint torques for the current state [N·m].
    pub fn torques(&self, scene: &mut Scene) -> Vec<f64> {
        let Terms {
            j,
            m,
            m_inv,
            lambda,
            g,
            q,
            qd,
            task,
        } = self.terms(scene);
        let n = q.len();
        let force = &lambda * task;
        let mut tau = j.transpose() * force;
        let j_bar = &m_inv * j.transpose() * &lambda;
        let null = DMatrix::identity(n, n) - j.transpose() * j_bar.transpose();
        let kd_null = 2.0 * self.params.null_kp.sqrt();
        let home = DVector::from_column_slice(&self.home);
        let posture = (&home - &q) * self.params.null_kp - &qd * kd_null;
        tau += null * (&m * posture);
        if self.params.friction_compensation {
            for (t, joint) in tau.iter_mut().zip(&scene.arm().model().joints) {
                if joint.friction > 0.0 {
                    *t += joint.friction * (*t / (0.05 * joint.friction)).tanh();
                }
            }
        }
        tau += g;
        tau.iter().copied().collect()
    }
}

/// The OSC law's pieces at one state.
struct Terms {
    j: DMatrix<f64>,
    m: DMatrix<f64>,
    m_inv: DMatrix<f64>,
    lambda: DMatrix<f64>,
    g: DVector<f64>,
    q: DVector<f64>,
    qd: DVector<f64>,
    task: DVector<f64>,
}

/// Moore–Penrose pseudo-inverse with small singular values cut (near singularities).
fn pseudo_inverse(a: &DMatrix<f64>) -> DMatrix<f64> {
    let svd = a.clone().svd(true, true);
    let max = svd.singular_values.max();
    svd.pseudo_inverse(max * 1e-6)
        .unwrap_or_else(|_| DMatrix::zeros(a.ncols(), a.nrows()))
}
