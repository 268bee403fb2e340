//! What a user configures about an arm's controller: its kind, impedance mode, action
//! scaling and control frequency (every field has the seed's/robosuite's default).

use serde::{Deserialize, Serialize};

use super::osc::OscParams;

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
    /// Actions per second \[Hz\]. Default 20 (robosuite's default; the seed trained at 500).
    pub control_freq: f64,
    /// Largest tip translation per action \[m\]. Default 0.05 (the seed's limit).
    pub position_limit: f64,
    /// Largest tip rotation per action \[rad\]. Default 0.5 (the seed's limit).
    pub rotation_limit: f64,
    /// Largest joint position change per action \[rad\]. Default 0.05.
    pub joint_delta_limit: f64,
    /// OSC gains (fixed mode, and the starting gains of the variable modes).
    pub osc: OscParams,
    /// Stiffness range of the variable modes [1/s²]. Default [10, 300] (robosuite's).
    pub kp_range: [f64; 2],
    /// Damping-ratio range of the variable mode. Default [0, 10] (robosuite's).
    pub damping_ratio_range: [f64; 2],
    /// Force the hybrid controller holds along the probe axis \[N\]. Default 5.
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
