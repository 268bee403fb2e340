//! [`ArmController`]: the action interface of an arm — robosuite's controller set with
//! its action scaling and control frequency.
//!
//! An action is a vector in [-1, 1] (clipped) set once per control period; the chosen
//! controller then computes torques every physics step towards the goal the action set
//! (`physics_steps_per_action = 1 / (control_freq · dt)`: 25 at the default 20 Hz and
//! 2 ms, 1 at the seed's training setting of 500 Hz).
//!
//! | kind | action | meaning |
//! |---|---|---|
//! | `osc_pose` + `fixed` | 6 | tip position delta (±`position_limit` m) and axis-angle delta (±`rotation_limit` rad), world frame |
//! | `osc_pose` + `variable_kp` | 12 | the 6 above, then kp per axis mapped onto `kp_range` |
//! | `osc_pose` + `variable` | 18 | the 12 above, then damping ratio per axis mapped onto `damping_ratio_range` |
//! | `joint_position` | dof | joint position deltas (±`joint_delta_limit` rad) |
//! | `joint_velocity` | dof | joint velocities (± each joint's velocity limit) |
//! | `joint_torque` | dof | joint torques (± each joint's effort limit), gravity compensated |
//! | `hybrid_force_motion` | 6 | tangent-plane position delta (3, the axial part ignored), rotation delta (3) — force along the probe axis held at `target_force` |

use super::config::{ControllerConfig, ControllerKind, ImpedanceMode};
use super::hybrid::HybridForceMotion;
use super::joint::{JointPosition, JointVelocity};
use super::osc::Osc;
use crate::sim::scene::Scene;

#[derive(Debug, Clone)]
enum Inner {
    Osc(Osc),
    JointPosition(JointPosition),
    JointVelocity(JointVelocity),
    JointTorque(Vec<f64>),
    Hybrid(HybridForceMotion),
}

/// An arm's controller: actions in, torques out.
#[derive(Debug, Clone)]
pub struct ArmController {
    config: ControllerConfig,
    inner: Inner,
}

/// Map `a ∈ [-1, 1]` onto `[lo, hi]`.
fn map_range(a: f64, [lo, hi]: [f64; 2]) -> f64 {
    lo + (a.clamp(-1.0, 1.0) + 1.0) / 2.0 * (hi - lo)
}

impl ArmController {
    /// A controller holding the scene's current state.
    pub fn new(config: ControllerConfig, scene: &Scene) -> Self {
        let inner = match config.kind {
            ControllerKind::OscPose => Inner::Osc(Osc::new(config.osc.clone(), scene)),
            ControllerKind::JointPosition => Inner::JointPosition(JointPosition::new(scene)),
            ControllerKind::JointVelocity => Inner::JointVelocity(JointVelocity::new(scene)),
            ControllerKind::JointTorque => Inner::JointTorque(vec![0.0; scene.arm().dof()]),
            ControllerKind::HybridForceMotion => Inner::Hybrid(HybridForceMotion::new(
                config.osc.clone(),
                scene,
                config.target_force,
            )),
        };
        Self { config, inner }
    }

    /// The configuration.
    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// Apply one action (clipped to [-1, 1]; its length must be
    /// [`ControllerConfig::action_size`]): sets the goal for the next control period.
    pub fn set_action(&mut self, scene: &Scene, action: &[f64]) {
        let a: Vec<f64> = action.iter().map(|x| x.clamp(-1.0, 1.0)).collect();
        let c = &self.config;
        let pose_delta = |a: &[f64]| {
            [
                a[0] * c.position_limit,
                a[1] * c.position_limit,
                a[2] * c.position_limit,
                a[3] * c.rotation_limit,
                a[4] * c.rotation_limit,
                a[5] * c.rotation_limit,
            ]
        };
        match &mut self.inner {
            Inner::Osc(osc) => {
                osc.set_goal_delta(scene, pose_delta(&a));
                if matches!(
                    c.impedance_mode,
                    ImpedanceMode::Variable | ImpedanceMode::VariableKp
                ) {
                    for k in 0..6 {
                        osc.params.kp[k] = map_range(a[6 + k], c.kp_range);
                    }
                }
                if c.impedance_mode == ImpedanceMode::Variable {
                    for k in 0..6 {
                        osc.params.damping_ratio[k] = map_range(a[12 + k], c.damping_ratio_range);
                    }
                }
            }
            Inner::Hybrid(hybrid) => hybrid.motion.set_goal_delta(scene, pose_delta(&a)),
            Inner::JointPosition(joint) => {
                let q = scene.arm().q(scene.world());
                for (k, goal) in joint.goal.iter_mut().enumerate() {
                    *goal = q[k] + a[k] * c.joint_delta_limit;
                }
            }
            Inner::JointVelocity(joint) => {
                for (k, goal) in joint.goal.iter_mut().enumerate() {
                    *goal = a[k] * scene.arm().model().joints[k].max_velocity;
                }
            }
            Inner::JointTorque(tau) => {
                for (k, t) in tau.iter_mut().enumerate() {
                    let limit = scene.arm().model().joints[k].max_effort;
                    *t = a[k] * if limit.is_finite() { limit } else { 100.0 };
                }
            }
        }
    }

    /// Torques for this physics step [N·m].
    pub fn torques(&mut self, scene: &mut Scene) -> Vec<f64> {
        match &mut self.inner {
            Inner::Osc(osc) => osc.torques(scene),
            Inner::Hybrid(hybrid) => hybrid.torques(scene),
            Inner::JointPosition(joint) => joint.torques(scene),
            Inner::JointVelocity(joint) => joint.torques(scene),
            Inner::JointTorque(tau) => {
                let g = scene.gravity_torques();
                tau.iter().zip(g).map(|(t, g)| t + g).collect()
            }
        }
    }

    /// Apply `action` and run one control period of physics steps.
    pub fn act(&mut self, scene: &mut Scene, action: &[f64]) {
        self.act_observed(scene, action, |_| {});
    }

    /// [`Self::act`], calling `after_step` with the scene after each physics step
    /// (task bookkeeping, recorders).
    pub fn act_observed(
        &mut self,
        scene: &mut Scene,
        action: &[f64],
        mut after_step: impl FnMut(&Scene),
    ) {
        self.set_action(scene, action);
        for _ in 0..self.config.physics_steps_per_action(scene.dt()) {
            let tau = self.torques(scene);
            scene.step(&tau);
            after_step(scene);
        }
    }
}
