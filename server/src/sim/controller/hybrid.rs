//! [`HybridForceMotion`]: the seed thesis's hybrid controller — force along the probe
//! axis, motion in the tangent plane and in orientation.
//!
//! With `n` the probe axis (world, pointing into the tissue) and the selection matrices
//! `S_f = n·nᵀ`, `S_m = I - S_f` on the linear part:
//! `τ = Jᵀ·Λ·[S_m·(Kp·e - Kd·ẋ); Kp_r·e_r - Kd_r·ω] + Jᵀ·[n·F_cmd - Λ_nn·Kd_f·(n·ẋ)·n; 0] + g(q)`,
//! `F_cmd = F* + Kf·(F* - F) + Ki·∫(F* - F)dt`, where `F` is the contact force along the
//! axis measured by the force-torque sensor (tool weight removed).

use rapier3d::na::{DVector, Matrix3, Vector3};
use rapier3d::prelude::*;

use super::osc::{Osc, OscParams, TaskTerms};
use crate::sim::scene::Scene;
use crate::sim::world::arr3;

/// Gains of the force loop.
#[derive(Debug, Clone, PartialEq)]
pub struct ForceGains {
    /// Proportional gain on the force error (dimensionless). Default 0.5.
    pub kf: f64,
    /// Integral gain on the force error [1/s]. Default 5.
    pub ki: f64,
    /// Damping along the axis [1/s] (scaled by the task inertia). Default 30.
    pub kd: f64,
}

impl Default for ForceGains {
    fn default() -> Self {
        Self {
            kf: 0.5,
            ki: 5.0,
            kd: 30.0,
        }
    }
}

/// Force along the probe axis, pose elsewhere.
#[derive(Debug, Clone)]
pub struct HybridForceMotion {
    /// Motion part (goal pose and gains); its goal's component along the axis is ignored.
    pub motion: Osc,
    /// Force loop gains.
    pub gains: ForceGains,
    /// Desired contact force along the probe axis \[N\]. Default 5 (the seed's target).
    pub force: f64,
    integral: f64,
}

impl HybridForceMotion {
    /// A controller holding the current pose in the tangent plane and pressing `force`.
    pub fn new(params: OscParams, scene: &Scene, force: f64) -> Self {
        Self {
            motion: Osc::new(params, scene),
            gains: ForceGains::default(),
            force,
            integral: 0.0,
        }
    }

    /// Contact force along the probe axis from the sensor, tool weight removed \[N\]
    /// (positive when pressing).
    pub fn measured_force(scene: &Scene) -> f64 {
        let reading = scene.ft_reading();
        let axis = scene.tip_pose().rotation * Vector::Z;
        let g = scene.world().gravity();
        let weight_along = scene.params().probe.mass
            * (g[0] * axis.x as f64 + g[1] * axis.y as f64 + g[2] * axis.z as f64);
        -(reading[2] - weight_along)
    }

    /// Joint torques for the current state [N·m]; integrates the force error over `dt`.
    pub fn torques(&mut self, scene: &mut Scene) -> Vec<f64> {
        let dt = scene.dt();
        let measured = Self::measured_force(scene);
        let error = self.force - measured;
        // Integrate only in contact: in free air the error is the whole target, and a
        // wound-up integral overshoots the force at touch-down.
        if scene.in_contact() {
            self.integral = (self.integral + error * dt).clamp(-20.0, 20.0);
        }
        let axis = arr3(scene.tip_pose().rotation * Vector::Z);
        let n = Vector3::new(axis[0], axis[1], axis[2]);
        let select_force = n * n.transpose();
        let select_motion = Matrix3::identity() - select_force;

        // Motion part: the OSC task force with its axial component removed.
        let TaskTerms { task, lambda, j, g } = self.motion.task_terms(scene);
        let mut selected = task;
        let lin = select_motion * Vector3::new(task[0], task[1], task[2]);
        selected[0] = lin.x;
        selected[1] = lin.y;
        selected[2] = lin.z;
        let mut wrench = lambda * selected;

        // Force part along the axis, with damping of the axial velocity.
        let (arm, world) = scene.arm_kinematics();
        let qd = DVector::from_vec(arm.qd(world));
        let v = &j * &qd;
        let v_axis = n.dot(&Vector3::new(v[0], v[1], v[2]));
        let lambda_nn = {
            let l = lambda.fixed_view::<3, 3>(0, 0);
            (n.transpose() * l * n)[(0, 0)]
        };
        let command = self.force + self.gains.kf * error + self.gains.ki * self.integral;
        let axial = n * command - n * (lambda_nn * self.gains.kd * v_axis);
        for k in 0..3 {
            wrench[k] += axial[k];
        }
        let tau: DVector<f64> = j.transpose() * wrench + g;
        tau.iter().copied().collect()
    }
}
