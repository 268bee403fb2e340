//! `echogym/CalibrationPress-v0`: press the probe into the torso at one of five sites
//! and record position, velocity and force (the report's calibration task, chapter 3.4).
//!
//! ## Description
//! The probe starts upright just above a site of the torso's top — the seed's five:
//! `upper_left`, `upper_right`, `center`, `lower_left`, `lower_right` (upper = +y, the
//! head end; left = −x) — and is pressed down. With `task.scripted` (default true) the
//! env runs the seed's protocol by itself and ignores the action: descend at
//! `press_speed` to `press_depth` below the rest surface, hold `hold_time`, withdraw at
//! the same speed; set `record` to write each press to the calibration tool's
//! `echogym-recordings/1` format. With `scripted = false` it is an RL env: the policy
//! presses, rewarded for tracking the target depth profile.
//!
//! ## Action space
//! `Box(-1, 1, (n,))` set by `controller`: default `osc_pose` (6) at 500 Hz with stiff
//! gains (kp 1500, a position-controlled arm like the seed's UR5e).
//!
//! ## Observation space
//! `Dict` of `observations` plus camera images (and the B-mode `ultrasound` image when
//! configured). `task_errors` (4): depth of the tip below
//! the rest surface \[m\], target depth of the protocol now \[m\], their difference \[m\],
//! contact force along the probe axis \[N\].
//!
//! ## Rewards
//! `exp(−(200·(depth − target))²)`: 1 on the protocol's depth profile.
//!
//! ## Starting state
//! Tip `task.start_height` above the site (inverse kinematics), nominal torso (no
//! randomization by default).
//!
//! ## Episode end
//! Terminated when the scripted protocol completes (also in RL mode, by time).
//! Truncated at `horizon` (4000 = 8 s at 500 Hz).
//!
//! ## Arguments
//! See [`CalibrationPressConfig`] and [`crate::envs::arena::ArenaConfig`].
//!
//! ## Version history
//! - v0: first version.

use rand::RngExt;
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};

use super::arena::{ArenaConfig, Randomization, Task, TaskConfig, upright};
use super::config::{EnvConfigError, check_range};
use super::env::Transition;
use super::ultrasound_scan::place_arm;
use crate::sim::controller::{ControllerConfig, ControllerKind, OscParams};
use crate::sim::scene::Scene;
use crate::sim::world::arr3;

/// The registered id.
pub const CALIBRATION_PRESS_ID: &str = "echogym/CalibrationPress-v0";

/// Integral gain of the scripted press's depth loop [1/s].
const PRESS_INTEGRAL_GAIN: f64 = 20.0;

/// The seed's five sites and their offsets from the torso's centre \[m\].
pub const SITES: [(&str, [f64; 2]); 5] = [
    ("upper_left", [-0.06, 0.08]),
    ("upper_right", [0.06, 0.08]),
    ("center", [0.0, 0.0]),
    ("lower_left", [-0.06, -0.08]),
    ("lower_right", [0.06, -0.08]),
];

/// Which site to press.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Site {
    /// Head end, −x.
    UpperLeft,
    /// Head end, +x.
    UpperRight,
    /// The centre.
    Center,
    /// Foot end, −x.
    LowerLeft,
    /// Foot end, +x.
    LowerRight,
    /// One of the five, drawn per episode.
    Random,
}

/// The task's settings (`task` key).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CalibrationPressConfig {
    /// The site. Default `random`.
    pub site: Site,
    /// Run the built-in protocol, ignoring actions. Default true.
    pub scripted: bool,
    /// Depth below the rest surface at the bottom of the press \[m\]. Default 0.015.
    pub press_depth: f64,
    /// Descent and withdrawal speed [m/s]. Default 0.01.
    pub press_speed: f64,
    /// Hold at depth \[s\]. Default 1.
    pub hold_time: f64,
    /// Tip height above the surface at the start \[m\]. Default 0.005.
    pub start_height: f64,
}

impl Default for CalibrationPressConfig {
    fn default() -> Self {
        Self {
            site: Site::Random,
            scripted: true,
            press_depth: 0.015,
            press_speed: 0.01,
            hold_time: 1.0,
            start_height: 0.005,
        }
    }
}

impl TaskConfig for CalibrationPressConfig {
    const ID: &'static str = CALIBRATION_PRESS_ID;
    const DESCRIPTION: &'static str = "press the probe into the torso at one of five sites and record force (the report's calibration)";

    fn arena_default() -> ArenaConfig<Self> {
        let mut config = ArenaConfig::base(Self::default());
        config.controller = ControllerConfig {
            control_freq: 500.0,
            osc: OscParams {
                kp: [1500.0; 6],
                ..OscParams::default()
            },
            ..ControllerConfig::default()
        };
        config.horizon = 4000;
        config.randomization = Randomization::none();
        config
    }

    fn validate(&self, arena: &ArenaConfig<Self>) -> Result<(), EnvConfigError> {
        let id = Self::ID;
        check_range(id, "task.press_depth", self.press_depth, 0.0, 0.05)?;
        check_range(id, "task.press_speed", self.press_speed, 1e-4, 0.5)?;
        check_range(id, "task.hold_time", self.hold_time, 0.0, 60.0)?;
        check_range(id, "task.start_height", self.start_height, 0.0, 0.1)?;
        if self.scripted && arena.controller.kind != ControllerKind::OscPose {
            return Err(EnvConfigError::Invalid {
                env_id: id.to_owned(),
                key: "task.scripted",
                message: "the scripted press drives `osc_pose`; set controller.kind to it".into(),
            });
        }
        if arena.torso.is_none() {
            return Err(EnvConfigError::Invalid {
                env_id: id.to_owned(),
                key: "torso",
                message: "the press needs a torso".into(),
            });
        }
        Ok(())
    }
}

const INFO_KEYS: [&str; 6] = [
    "site_index",
    "depth",
    "target_depth",
    "contact_force",
    "phase",
    "is_success",
];

/// The press's state.
pub struct CalibrationPress {
    config: CalibrationPressConfig,
    period: f64,
    position_limit: f64,
    rotation_limit: f64,
    action_size: usize,
    last_target: f64,
    site: usize,
    xy: [f64; 2],
    surface_z: f64,
    elapsed: f64,
    integral: f64,
    start_height: f64,
}

impl CalibrationPress {
    /// Target depth below the rest surface at time `t` \[m\] (negative: above) and the
    /// protocol phase (0 descend, 1 hold, 2 withdraw, 3 done).
    fn profile(&self, c: &CalibrationPressConfig, t: f64) -> (f64, u8) {
        let travel = self.start_height + c.press_depth;
        let down = travel / c.press_speed;
        if t < down {
            (-self.start_height + c.press_speed * t, 0)
        } else if t < down + c.hold_time {
            (c.press_depth, 1)
        } else if t < 2.0 * down + c.hold_time {
            (c.press_depth - c.press_speed * (t - down - c.hold_time), 2)
        } else {
            (-self.start_height, 3)
        }
    }

    fn depth(&self, scene: &Scene) -> f64 {
        self.surface_z - arr3(scene.tip_pose().translation)[2]
    }
}

impl Task for CalibrationPress {
    type Config = CalibrationPressConfig;
    const TASK_ERRORS: usize = 4;

    fn info_keys() -> &'static [&'static str] {
        &INFO_KEYS
    }

    fn new(config: &ArenaConfig<Self::Config>, scene: &mut Scene) -> Self {
        Self {
            config: config.task.clone(),
            period: 1.0 / config.controller.control_freq,
            position_limit: config.controller.position_limit,
            rotation_limit: config.controller.rotation_limit,
            action_size: config.controller.action_size(scene.arm().dof()),
            last_target: 0.0,
            site: 2,
            xy: [0.0; 2],
            surface_z: 0.0,
            elapsed: 0.0,
            integral: 0.0,
            start_height: 0.0,
        }
    }

    fn reset(&mut self, config: &ArenaConfig<Self::Config>, scene: &mut Scene, rng: &mut Pcg64Mcg) {
        let c = &config.task;
        self.site = match c.site {
            Site::UpperLeft => 0,
            Site::UpperRight => 1,
            Site::Center => 2,
            Site::LowerLeft => 3,
            Site::LowerRight => 4,
            Site::Random => rng.random_range(0..SITES.len()),
        };
        let torso = scene
            .torso()
            .expect("validated: the press has a torso")
            .params()
            .clone();
        let offset = SITES[self.site].1;
        self.xy = [
            torso.center_xy[0] + offset[0],
            torso.center_xy[1] + offset[1],
        ];
        self.surface_z = torso.top_z();
        self.elapsed = 0.0;
        self.integral = 0.0;
        self.start_height = c.start_height;
        self.last_target = -c.start_height;
        let position = [self.xy[0], self.xy[1], self.surface_z + c.start_height];
        place_arm(
            scene,
            position,
            upright(),
            config.randomization.joint_noise,
            rng,
        );
    }

    fn action(&mut self, scene: &Scene, action: &[f64]) -> Vec<f64> {
        if !self.config.scripted {
            return action.to_vec();
        }
        // Track the protocol's next depth with a PI law on the tip position (the
        // integral overcomes the tissue's push against the arm's finite stiffness).
        let (target, _) = self.profile(&self.config, self.elapsed + self.period);
        let tip = scene.tip_pose();
        let p = arr3(tip.translation);
        let desired = [self.xy[0], self.xy[1], self.surface_z - target];
        let e = [desired[0] - p[0], desired[1] - p[1], desired[2] - p[2]];
        self.integral = (self.integral + e[2] * self.period).clamp(-0.05, 0.05);
        let rot = (upright() * tip.rotation.inverse()).to_scaled_axis();
        let mut out = vec![0.0; self.action_size];
        out[0] = e[0] / self.position_limit;
        out[1] = e[1] / self.position_limit;
        out[2] = (e[2] + PRESS_INTEGRAL_GAIN * self.integral) / self.position_limit;
        out[3] = rot.x as f64 / self.rotation_limit;
        out[4] = rot.y as f64 / self.rotation_limit;
        out[5] = rot.z as f64 / self.rotation_limit;
        out
    }

    fn evaluate(
        &mut self,
        config: &ArenaConfig<Self::Config>,
        scene: &Scene,
        info: &mut [f32],
    ) -> Transition {
        let c = &config.task;
        self.elapsed += 1.0 / config.controller.control_freq;
        let (target, phase) = self.profile(c, self.elapsed);
        self.last_target = target;
        let depth = self.depth(scene);
        let force = scene.axial_contact_force();
        let done = phase == 3;
        let values = [
            self.site as f64,
            depth,
            target,
            force,
            f64::from(phase),
            f64::from(u8::from(done)),
        ];
        for (slot, v) in info.iter_mut().zip(values) {
            *slot = v as f32;
        }
        Transition {
            reward: (-(200.0 * (depth - target)).powi(2)).exp() as f32,
            terminated: done,
        }
    }

    fn task_errors(&self, scene: &Scene, out: &mut [f32]) {
        let depth = self.depth(scene);
        let target = self.last_target;
        let values = [depth, target, depth - target, scene.axial_contact_force()];
        for (o, v) in out.iter_mut().zip(values) {
            *o = v as f32;
        }
    }

    fn focus(&self, _scene: &Scene) -> [f64; 3] {
        [self.xy[0], self.xy[1], self.surface_z]
    }

    fn recording_labels(&self) -> (String, String) {
        (SITES[self.site].0.into(), "press".into())
    }
}
