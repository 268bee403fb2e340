//! Joint-space controllers (robosuite's `JOINT_POSITION` and `JOINT_VELOCITY`), with
//! gravity compensation. Joint torque control needs no controller: `Scene::step(τ)`.

use rapier3d::na::DVector;

use crate::sim::scene::Scene;

/// Joint position control: `τ = M(q)·(Kp·(q* - q) - Kd·q̇) + g(q)`, `Kd = 2·ζ·√Kp`.
#[derive(Debug, Clone)]
pub struct JointPosition {
    /// Stiffness [1/s²]. Default 50 (robosuite's default).
    pub kp: f64,
    /// Damping ratio. Default 1.
    pub damping_ratio: f64,
    /// Goal joint positions \[rad\].
    pub goal: Vec<f64>,
}

impl JointPosition {
    /// A controller holding the current configuration.
    pub fn new(scene: &Scene) -> Self {
        Self {
            kp: 50.0,
            damping_ratio: 1.0,
            goal: scene.arm().q(scene.world()),
        }
    }

    /// Joint torques for the current state [N·m].
    pub fn torques(&self, scene: &mut Scene) -> Vec<f64> {
        let (arm, world) = scene.arm_kinematics();
        let q = arm.q(world);
        let qd = arm.qd(world);
        let kd = 2.0 * self.damping_ratio * self.kp.sqrt();
        let accel = DVector::from_iterator(
            q.len(),
            (0..q.len()).map(|i| self.kp * (self.goal[i] - q[i]) - kd * qd[i]),
        );
        let tau = arm.mass_matrix(world) * accel + arm.gravity_torques(world);
        tau.iter().copied().collect()
    }
}

/// Joint velocity control: `τ = M(q)·Kv·(q̇* - q̇) + g(q)`.
#[derive(Debug, Clone)]
pub struct JointVelocity {
    /// Gain [1/s]. Default 20 (a 50 ms velocity time constant).
    pub kv: f64,
    /// Goal joint velocities [rad/s].
    pub goal: Vec<f64>,
}

impl JointVelocity {
    /// A controller holding still.
    pub fn new(scene: &Scene) -> Self {
        Self {
            kv: 20.0,
            goal: vec![0.0; scene.arm().dof()],
        }
    }

    /// Joint torques for the current state [N·m].
    pub fn torques(&self, scene: &mut Scene) -> Vec<f64> {
        let (arm, world) = scene.arm_kinematics();
        let qd = arm.qd(world);
        let accel = DVector::from_iterator(
            qd.len(),
            (0..qd.len()).map(|i| self.kv * (self.goal[i] - qd[i])),
        );
        let tau = arm.mass_matrix(world) * accel + arm.gravity_torques(world);
        tau.iter().copied().collect()
    }
}
