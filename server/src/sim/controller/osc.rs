//! [`Osc`]: operational-space pose control of the probe tip (robosuite's `OSC_POSE`).
//!
//! `τ = Jᵀ·Λ·(Kp·e - Kd·ẋ) + g(q) + N·(Kp_null·(q_home - q) - Kd_null·q̇)` with the task-space
//! inertia `Λ = (J·M⁻¹·Jᵀ)⁻¹`, the tip Jacobian `J` (6 × dof, world frame), position and
//! orientation errors `e` (axis-angle), `Kd = 2·ζ·√Kp`, and the dynamically consistent
//! null-space projector `N = I - Jᵀ·J̄ᵀ`, `J̄ = M⁻¹·Jᵀ·Λ` (keeps redundant arms near home).
//!
//! Runs every physics step, so it avoids what costs most at these sizes (dof ≤ 7): `M⁻¹·Jᵀ`
//! comes from a Cholesky solve rather than an inverse, Λ is a fixed-size 6 × 6 whose
//! pseudo-inverse is a symmetric eigendecomposition, and `N` is applied to a vector
//! (`y - Jᵀ·(J̄ᵀ·y)`) rather than formed.

use rapier3d::na::{DMatrix, DVector, Matrix6, Matrix6xX, MatrixXx6, Vector6};
use rapier3d::prelude::*;
use serde::{Deserialize, Serialize};

use crate::sim::scene::Scene;
use crate::sim::world::{arr3, vec3};

/// The OSC's pieces that other controllers reuse (the hybrid force/motion law).
pub(crate) struct TaskTerms {
    /// Desired task acceleration `Kp·e - Kd·ẋ` (linear, angular).
    pub task: Vector6<f64>,
    /// Task-space inertia Λ.
    pub lambda: Matrix6<f64>,
    /// Tip Jacobian.
    pub j: Matrix6xX<f64>,
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
        let jt = j.transpose();
        // M is symmetric positive definite for any real arm; the fallbacks keep a
        // degenerate model (massless links) from producing NaN.
        let m_inv_jt: MatrixXx6<f64> = match m.clone().cholesky() {
            Some(chol) => chol.solve(&jt),
            None => m.clone().try_inverse().map_or(jt.clone(), |inv| inv * &jt),
        };
        let lambda = pseudo_inverse(&(&j * &m_inv_jt));
        let mut e = Vector6::zeros();
        for k in 0..3 {
            e[k] = self.goal_position[k] - tip_p[k];
        }
        let rot_err = (self.goal_rotation * tip.rotation.inverse()).to_scaled_axis();
        e[3] = rot_err.x as f64;
        e[4] = rot_err.y as f64;
        e[5] = rot_err.z as f64;
        let v = &j * &qd;
        let task = Vector6::from_fn(|k, _| {
            let kp = self.params.kp[k];
            let kd = 2.0 * self.params.damping_ratio[k] * kp.sqrt();
            kp * e[k] - kd * v[k]
        });
        Terms {
            j,
            m,
            m_inv_jt,
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
            m_inv_jt,
            lambda,
            g,
            q,
            qd,
            task,
        } = self.terms(scene);
        let mut tau = j.tr_mul(&(lambda * task));
        // Null space: N·y = y - Jᵀ·(J̄ᵀ·y) with J̄ᵀ = Λ·J·M⁻¹ = Λ·(M⁻¹·Jᵀ)ᵀ (M, Λ symmetric).
        let kd_null = 2.0 * self.params.null_kp.sqrt();
        let home = DVector::from_column_slice(&self.home);
        let posture = (&home - &q) * self.params.null_kp - &qd * kd_null;
        let y = &m * posture;
        let j_bar_t_y = lambda * m_inv_jt.tr_mul(&y);
        tau += &y - j.tr_mul(&j_bar_t_y);
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
    j: Matrix6xX<f64>,
    m: DMatrix<f64>,
    /// `M⁻¹·Jᵀ` (dof × 6).
    m_inv_jt: MatrixXx6<f64>,
    lambda: Matrix6<f64>,
    g: DVector<f64>,
    q: DVector<f64>,
    qd: DVector<f64>,
    task: Vector6<f64>,
}

/// Moore–Penrose pseudo-inverse of a symmetric positive semi-definite matrix, with
/// eigenvalues below 10⁻⁶ of the largest cut (near singularities).
///
/// Away from singularities that is the plain inverse: when `‖A‖_F·‖A⁻¹‖_F < 10⁶` the
/// condition number (≤ that product) is below 10⁶, so no eigenvalue is cut, and a 6 × 6
/// Cholesky inverse is ≈ 10× cheaper than the eigendecomposition the general case needs.
fn pseudo_inverse(a: &Matrix6<f64>) -> Matrix6<f64> {
    const CUT: f64 = 1e-6;
    if let Some(chol) = a.cholesky() {
        let inverse = chol.inverse();
        if a.norm() * inverse.norm() < 1.0 / CUT {
            return inverse;
        }
    }
    // Bounded iterations: nalgebra's default (unbounded) never returns on NaN input.
    let Some(eigen) = a.try_symmetric_eigen(f64::EPSILON, 1000) else {
        return Matrix6::zeros();
    };
    let cut = eigen.eigenvalues.amax() * CUT;
    let mut inverse = Matrix6::zeros();
    for (k, &value) in eigen.eigenvalues.iter().enumerate() {
        if value.abs() > cut {
            let v = eigen.eigenvectors.column(k);
            inverse += v * v.transpose() / value;
        }
    }
    inverse
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spd(scales: [f64; 6]) -> Matrix6<f64> {
        let q = rapier3d::na::Rotation3::from_euler_angles(0.3, -0.7, 1.1).into_inner();
        let mut r = Matrix6::identity();
        r.fixed_view_mut::<3, 3>(0, 0).copy_from(&q);
        r.fixed_view_mut::<3, 3>(3, 3).copy_from(&q.transpose());
        r * Matrix6::from_diagonal(&Vector6::from(scales)) * r.transpose()
    }

    fn svd_pseudo_inverse(a: &Matrix6<f64>) -> Matrix6<f64> {
        let svd = a.svd(true, true);
        let max = svd.singular_values.max();
        svd.pseudo_inverse(max * 1e-6).unwrap()
    }

    #[test]
    fn the_pseudo_inverse_matches_the_svd_one_on_both_paths() {
        let cases = [
            [2.0, 0.5, 3.0, 1e-2, 4e-3, 7e-2], // well conditioned: the Cholesky path
            [2.0, 0.5, 3.0, 1e-2, 4e-3, 1e-9], // near singular: one direction cut
            [2.0, 0.5, 3.0, 0.0, 0.0, 0.0],    // rank 3
            [1.0, 1.0, 1.0, 1.0, 1.0, 3e-6],   // just above the cut: kept
        ];
        for scales in cases {
            let a = spd(scales);
            let (ours, svd) = (pseudo_inverse(&a), svd_pseudo_inverse(&a));
            let error = (ours - svd).amax() / svd.amax();
            assert!(error < 1e-6, "{scales:?}: relative difference {error:e}");
        }
        assert_eq!(pseudo_inverse(&Matrix6::zeros()), Matrix6::zeros());
        // Returns (nalgebra's unbounded decomposition would spin on NaN) with zeros.
        assert_eq!(
            pseudo_inverse(&Matrix6::from_element(f64::NAN)),
            Matrix6::zeros()
        );
    }
}
