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

use serde::{Deserialize, Serialize};

use super::hybrid::HybridForceMotion;
use super::joint::{JointPosition, JointVelocity};
use super::osc::{Osc, OscParams};
use crate::sim::scene::Scene;

/// Which controller turns actions into torques.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ControllerKind {
    /// Operational-space pose control of the probe tip (robosuite's `OSC_POSE`).
    #[default]
    OscPose,
    /// Joint position deltas.
    JointPosition,
    /// Joint velocities.
    JointVelocity,
    /// Joint torques.
    JointTorque,
    /// Force along the probe axis, motion elsewhere (the seed thesis's controller).
    HybridForceMotion,
}

/// OSC impedance mode (robosuite's names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ImpedanceMode {
    /// Gains fixed by the config.
    #[default]
    Fixed,
    /// Stiffness and damping ratio in the action.
    Variable,
    /// Stiffness in the action, damping critical.
    VariableKp,
}

/// Controller configuration (every field has the seed's/robosuite's default).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerConfig {
    /// The controller. Default `osc_pose`.
    pub kind: ControllerKind,
    /// OSC impedance mode. Default `fixed`.
    pub impedance_mode: ImpedanceMode,
    /// Actions per second [Hz]. Default 20 (robosuite's default; the seed trained at 500).
    pub control_freq: f64,
    /// Largest tip translation per action [m]. Default 0.05 (the seed's limit).
    pub position_limit: f64,
    /// Largest tip rotation per action [rad]. Default 0.5 (the seed's limit).
    pub rotation_limit: f64,
    /// Largest joint position change per action [rad]. Default 0.05.
    pub joint_delta_limit: f64,
    /// OSC gains (fixed mode, and the starting gains of the variable modes).
    pub osc: OscParams,
    /// Stiffness range of the variable modes [1/s²]. Default [10, 300] (robosuite's).
    pub kp_range: [f64; 2],
    /// Damping-ratio range of the variable mode. Default [0, 10] (robosuite's).
    pub damping_ratio_range: [f64; 2],
    /// Force the hybrid controller holds along the probe axis [N]. Default 5.
    pub target_force: f64,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        Self {
            kind: ControllerKind::OscPose,
            impedance_mode: ImpedanceMode::Fixed,
            control_freq: 20.0,
            position_limit: 0.05,
            rotation_limit: 0.5,
            joint_delta_limit: 0.05,
            osc: OscParams::default(),
            kp_range: [10.0, 300.0],
            damping_ratio_range: [0.0, 10.0],
            target_force: 5.0,
        }
    }
}

/// A controller configuration value out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("controller `{key}` must be {expected}")]
pub struct ControllerConfigError {
    /// The key.
    pub key: &'static str,
    /// The allowed range.
    pub expected: &'static str,
}

impl ControllerConfig {
    /// Check ranges against the physics timestep `dt`.
    pub fn validate(&self, dt: f64) -> Result<(), ControllerConfigError> {
        let err = |key, expected| Err(ControllerConfigError { key, expected });
        if !(self.control_freq > 0.0 && self.control_freq <= 1.0 / dt + 1e-9) {
            return err(
                "control_freq",
                "positive and at most the physics rate (500 Hz at 2 ms)",
            );
        }
        if !(self.position_limit > 0.0 && self.position_limit <= 0.5) {
            return err("position_limit", "in (0, 0.5] m");
        }
        if !(self.rotation_limit > 0.0 && self.rotation_limit <= 3.2) {
            return err("rotation_limit", "in (0, 3.2] rad");
        }
        if !(self.joint_delta_limit > 0.0 && self.joint_delta_limit <= 1.0) {
            return err("joint_delta_limit", "in (0, 1] rad");
        }
        if !(self.kp_range[0] > 0.0 && self.kp_range[0] <= self.kp_range[1]) {
            return err("kp_range", "positive and ordered");
        }
        if !(self.damping_ratio_range[0] >= 0.0
            && self.damping_ratio_range[0] <= self.damping_ratio_range[1])
        {
            return err("damping_ratio_range", "non-negative and ordered");
        }
        if !(0.0..=100.0).contains(&self.target_force) {
            return err("target_force", "in [0, 100] N");
        }
        Ok(())
    }

    /// Action length for an arm of `dof` joints.
    pub fn action_size(&self, dof: usize) -> usize {
        match self.kind {
            ControllerKind::OscPose => match self.impedance_mode {
                ImpedanceMode::Fixed => 6,
                ImpedanceMode::VariableKp => 12,
                ImpedanceMode::Variable => 18,
            },
            ControllerKind::HybridForceMotion => 6,
            _ => dof,
        }
    }

    /// Physics steps per action at timestep `dt`.
    pub fn physics_steps_per_action(&self, dt: f64) -> usize {
        ((1.0 / (self.control_freq * dt)).round() as usize).max(1)
    }
}

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
        self.set_action(scene, action);
        for _ in 0..self.config.physics_steps_per_action(scene.dt()) {
            let tau = self.torques(scene);
            scene.step(&tau);
        }
    }
}
