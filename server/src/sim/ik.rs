//! Inverse kinematics of the probe tip: damped least squares on the tip Jacobian, with
//! joint limits, for placing the arm at an episode's starting pose (no physics runs).

use rapier3d::na::{Matrix6, Vector6};
use rapier3d::prelude::*;

use super::scene::Scene;
use super::world::arr3;

/// Damping of the least-squares step \[m\] (keeps steps bounded near singularities).
const DAMPING: f64 = 0.05;
/// Iteration cap.
const MAX_ITERATIONS: usize = 200;

/// No joint configuration reached the pose.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "inverse kinematics did not reach the pose: {position_error:.4} m, {rotation_error:.4} rad off"
)]
pub struct IkError {
    /// Remaining position error \[m\].
    pub position_error: f64,
    /// Remaining rotation error \[rad\].
    pub rotation_error: f64,
}

/// Move the arm (teleport, zero velocity) so the probe tip reaches `position` [m, world]
/// with `rotation`, starting from joint positions `q0`; returns the joint positions.
/// Succeeds within 0.1 mm and 1 mrad.
pub fn solve_tip_pose(
    scene: &mut Scene,
    position: [f64; 3],
    rotation: Rotation,
    q0: &[f64],
) -> Result<Vec<f64>, IkError> {
    let joints = scene.arm().model().joints.clone();
    let n = joints.len();
    let mut q = q0.to_vec();
    let zero = vec![0.0; n];
    let mut errors = (f64::INFINITY, f64::INFINITY);
    for _ in 0..MAX_ITERATIONS {
        scene.set_arm_state(&q, &zero);
        let tip = scene.tip_pose();
        let p = arr3(tip.translation);
        let rot_err = (rotation * tip.rotation.inverse()).to_scaled_axis();
        let e = Vector6::new(
            position[0] - p[0],
            position[1] - p[1],
            position[2] - p[2],
            rot_err.x as f64,
            rot_err.y as f64,
            rot_err.z as f64,
        );
        errors = (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm());
        if errors.0 < 1e-4 && errors.1 < 1e-3 {
            return Ok(q);
        }
        let (arm, world) = scene.arm_kinematics();
        let j = arm.point_jacobian(world, p);
        let jjt = &j * j.transpose() + Matrix6::identity() * (DAMPING * DAMPING);
        let Some(step) = jjt.lu().solve(&e) else {
            break;
        };
        let dq = j.transpose() * step;
        for k in 0..n {
            let (lo, hi) = (joints[k].lower, joints[k].upper);
            q[k] = (q[k] + dq[k].clamp(-0.3, 0.3)).clamp(lo, hi);
        }
    }
    Err(IkError {
        position_error: errors.0,
        rotation_error: errors.1,
    })
}
