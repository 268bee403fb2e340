//! `echogym/UltrasoundScan-v0`: sweep the probe across the soft torso along a line on its
//! surface, pressing with a target force at a target speed, probe upright.
//!
//! ## Description
//! The seed thesis's ultrasound task. A UR5e or Panda holds a linear ultrasound probe
//! over the soft torso (spring-damper particle joints). Each episode draws a straight
//! trajectory on the torso's top (random start and heading, 3 cm clear of the edges;
//! `task.trajectory = "fixed"`: along y through the centre); its target point moves from
//! the start at `task.target_speed`, so the path's length is `target_speed × horizon ×
//! control period`. The policy must follow the point while pressing `task.target_force`
//! along the probe axis with the probe upright (face down, array along world y).
//!
//! ## Action space
//! `Box(-1, 1, (n,))` set by `controller` (see [`crate::sim::controller`]): default
//! `osc_pose` (6: tip position delta ±0.05 m and axis-angle delta ±0.5 rad per action)
//! at 500 Hz; `hybrid_force_motion` holds the force itself and the action moves the
//! probe in the tangent plane.
//!
//! ## Observation space
//! A `Dict` of the fields in `observations` (default `joint_pos`, `joint_vel`,
//! `probe_pose`, `probe_vel`, `ft`, `contact`, `task_errors`) plus camera images, and
//! with `ultrasound` set the probe's B-mode image (`ultrasound`, uint8 `[rows, lines]`;
//! `us_*` info; docs/ultrasound.md). `task_errors` (8): tip minus target point `[dx, dy, dz]` \[m\] (target z = the skin's
//! rest height), smoothed contact force minus target \[N\], mean speed minus target
//! [m/s], orientation error \[rad\], the target point's velocity `[vx, vy]` [m/s].
//!
//! ## Rewards
//! The seed's five shaped terms, each `R·exp(−e)` with `e` a weighted squared error
//! (weights in `task.reward`, defaults the seed's):
//! position `5·exp(−‖(90·Δxy)²‖)`; orientation `1·exp(−0.2·angle)`; speed
//! `1·exp(−(45·(v̄ − v*))²)` with `v̄` the episode's mean tip speed; force
//! `3·exp(−(0.7·(F̄ − F*))²)` with `F̄` an exponential moving average (α = 0.1) of the
//! contact force along the probe axis; force derivative `2·exp(−(0.01·dF/dt)²)`. The
//! last two count only while the probe touches the torso. Each term is in `info`.
//!
//! ## Starting state
//! The probe hovers `task.start_height` (5 mm) above the trajectory's start, upright
//! (inverse kinematics), plus Gaussian position noise; torso, sensor, probe mass and
//! breathing drawn from `randomization`.
//!
//! ## Episode end
//! Terminated (seed's early termination, `task.early_termination`): a joint within
//! 0.05 rad of its limit; `‖(90·Δxy)²‖ > 1` (≈ 11 mm off the path); orientation error
//! above `0.1/0.2 = 0.5` rad while touching; contact lost for longer than
//! `task.contact_loss_grace` after the first touch. Truncated at `horizon` (1000).
//!
//! ## Arguments
//! See [`UltrasoundScanConfig`] and [`crate::envs::arena::ArenaConfig`].
//!
//! ## Version history
//! - v0: first version.

use rand::RngExt;
use rand_pcg::Pcg64Mcg;
use rapier3d::prelude::*;
use serde::{Deserialize, Serialize};

use super::arena::{ArenaConfig, Randomization, Task, TaskConfig, gaussian, upright};
use super::config::{EnvConfigError, check_range};
use super::env::Transition;
use crate::sim::controller::ControllerConfig;
use crate::sim::ik::solve_tip_pose;
use crate::sim::scene::Scene;
use crate::sim::torso::BreathingParams;
use crate::sim::world::arr3;

/// The registered id.
pub const ULTRASOUND_SCAN_ID: &str = "echogym/UltrasoundScan-v0";

/// The seed's reward weights: `*_error` multiplies the error, `*_reward` the term.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ScanRewardWeights {
    /// Position error multiplier [1/m]. Default 90.
    pub position_error: f64,
    /// Position term weight. Default 5.
    pub position_reward: f64,
    /// Orientation error multiplier [1/rad]. Default 0.2.
    pub orientation_error: f64,
    /// Orientation term weight. Default 1.
    pub orientation_reward: f64,
    /// Speed error multiplier [s/m]. Default 45.
    pub speed_error: f64,
    /// Speed term weight. Default 1.
    pub speed_reward: f64,
    /// Force error multiplier [1/N]. Default 0.7.
    pub force_error: f64,
    /// Force term weight. Default 3.
    pub force_reward: f64,
    /// Force-derivative error multiplier [s/N]. Default 0.01.
    pub force_derivative_error: f64,
    /// Force-derivative term weight. Default 2.
    pub force_derivative_reward: f64,
}

impl Default for ScanRewardWeights {
    fn default() -> Self {
        Self {
            position_error: 90.0,
            position_reward: 5.0,
            orientation_error: 0.2,
            orientation_reward: 1.0,
            speed_error: 45.0,
            speed_reward: 1.0,
            force_error: 0.7,
            force_reward: 3.0,
            force_derivative_error: 0.01,
            force_derivative_reward: 2.0,
        }
    }
}

/// How the trajectory is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrajectoryKind {
    /// Random start and heading on the top.
    Random,
    /// Along world y through the torso's centre.
    Fixed,
}

/// The task's settings (`task` key).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct UltrasoundScanConfig {
    /// Contact force to hold along the probe axis \[N\]. Default 5 (the seed's).
    pub target_force: f64,
    /// Sweep speed [m/s]. Default 0.04 (the seed's).
    pub target_speed: f64,
    /// Trajectory kind. Default `random`.
    pub trajectory: TrajectoryKind,
    /// Clearance of the trajectory from the top's edges \[m\]. Default 0.03.
    pub edge_margin: f64,
    /// Height of the probe face above the skin at the start \[m\]. Default 0.005.
    pub start_height: f64,
    /// Reward weights.
    pub reward: ScanRewardWeights,
    /// Smoothing factor of the force's moving average (the seed's α). Default 0.1.
    pub force_smoothing: f64,
    /// The seed's early termination. Default true.
    pub early_termination: bool,
    /// Terminate when `‖(position_error·Δxy)²‖` exceeds this. Default 1 (the seed's).
    pub position_error_threshold: f64,
    /// Terminate when `orientation_error·angle` exceeds this while touching. Default
    /// 0.1 (the seed's).
    pub orientation_error_threshold: f64,
    /// Contact may be lost this long \[s\] after the first touch before the episode
    /// terminates. Default 0.05 (the seed: 0, one MuJoCo step; a 2 ms bounce of the
    /// stiff contact would end episodes).
    pub contact_loss_grace: f64,
}

impl Default for UltrasoundScanConfig {
    fn default() -> Self {
        Self {
            target_force: 5.0,
            target_speed: 0.04,
            trajectory: TrajectoryKind::Random,
            edge_margin: 0.03,
            start_height: 0.005,
            reward: ScanRewardWeights::default(),
            force_smoothing: 0.1,
            early_termination: true,
            position_error_threshold: 1.0,
            orientation_error_threshold: 0.1,
            contact_loss_grace: 0.05,
        }
    }
}

impl TaskConfig for UltrasoundScanConfig {
    const ID: &'static str = ULTRASOUND_SCAN_ID;
    const DESCRIPTION: &'static str =
        "sweep the probe along a line on the soft torso at 5 N and 4 cm/s (the seed's task)";

    fn arena_default() -> ArenaConfig<Self> {
        let mut config = ArenaConfig::base(Self::default());
        config.controller = ControllerConfig {
            control_freq: 500.0,
            ..ControllerConfig::default()
        };
        config.horizon = 1000;
        config.breathing = Some(BreathingParams::default());
        config.randomization = Randomization {
            joint_noise: 0.0,
            ..Randomization::default()
        };
        config
    }

    fn validate(&self, arena: &ArenaConfig<Self>) -> Result<(), EnvConfigError> {
        let id = Self::ID;
        check_range(id, "task.target_force", self.target_force, 0.0, 100.0)?;
        check_range(id, "task.target_speed", self.target_speed, 0.0, 1.0)?;
        check_range(id, "task.edge_margin", self.edge_margin, 0.0, 0.2)?;
        check_range(id, "task.start_height", self.start_height, 0.0, 0.3)?;
        check_range(id, "task.force_smoothing", self.force_smoothing, 1e-6, 1.0)?;
        check_range(
            id,
            "task.position_error_threshold",
            self.position_error_threshold,
            0.0,
            1e9,
        )?;
        check_range(
            id,
            "task.orientation_error_threshold",
            self.orientation_error_threshold,
            0.0,
            1e9,
        )?;
        check_range(
            id,
            "task.contact_loss_grace",
            self.contact_loss_grace,
            0.0,
            1e3,
        )?;
        let r = &self.reward;
        for (key, v) in [
            ("task.reward.position_error", r.position_error),
            ("task.reward.position_reward", r.position_reward),
            ("task.reward.orientation_error", r.orientation_error),
            ("task.reward.orientation_reward", r.orientation_reward),
            ("task.reward.speed_error", r.speed_error),
            ("task.reward.speed_reward", r.speed_reward),
            ("task.reward.force_error", r.force_error),
            ("task.reward.force_reward", r.force_reward),
            (
                "task.reward.force_derivative_error",
                r.force_derivative_error,
            ),
            (
                "task.reward.force_derivative_reward",
                r.force_derivative_reward,
            ),
        ] {
            check_range(id, key, v, 0.0, 1e6)?;
        }
        match &arena.torso {
            Some(t) => {
                let room = t.size[0].min(t.size[1]) / 2.0;
                check_range(id, "task.edge_margin", self.edge_margin, 0.0, room - 0.01)
            }
            None => Err(EnvConfigError::Invalid {
                env_id: id.to_owned(),
                key: "torso",
                message: "the scan needs a torso".into(),
            }),
        }
    }
}

/// Info values, in order.
const INFO_KEYS: [&str; 14] = [
    "reward_position",
    "reward_orientation",
    "reward_speed",
    "reward_force",
    "reward_force_derivative",
    "contact_force",
    "force_error",
    "speed",
    "trajectory_error",
    "orientation_error",
    "progress",
    "in_contact",
    "is_success",
    "termination",
];

/// Why an episode terminated (`info["termination"]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum ScanTermination {
    /// Still running (or truncated).
    None = 0,
    /// A joint reached its limit.
    JointLimit = 1,
    /// The probe left the trajectory.
    OffTrajectory = 2,
    /// Bad orientation while touching.
    Orientation = 3,
    /// Contact lost after the first touch.
    LostContact = 4,
}

/// The scan's per-episode state.
pub struct UltrasoundScan {
    start: [f64; 2],
    direction: [f64; 2],
    length: f64,
    surface_z: f64,
    elapsed: f64,
    control_steps: u64,
    mean_speed: f64,
    force_average: f64,
    previous_force: f64,
    touched: bool,
    out_of_contact: f64,
    target_speed: f64,
    force_error: f64,
    speed_error: f64,
}

impl UltrasoundScan {
    /// The target point now [m, world].
    fn target(&self) -> [f64; 3] {
        let s = (self.target_speed * self.elapsed).min(self.length);
        [
            self.start[0] + s * self.direction[0],
            self.start[1] + s * self.direction[1],
            self.surface_z,
        ]
    }
}

impl Task for UltrasoundScan {
    type Config = UltrasoundScanConfig;
    const TASK_ERRORS: usize = 8;

    fn info_keys() -> &'static [&'static str] {
        &INFO_KEYS
    }

    fn new(_config: &ArenaConfig<Self::Config>, _scene: &mut Scene) -> Self {
        Self {
            start: [0.0; 2],
            direction: [0.0, 1.0],
            length: 0.0,
            surface_z: 0.0,
            elapsed: 0.0,
            control_steps: 0,
            mean_speed: 0.0,
            force_average: 0.0,
            previous_force: 0.0,
            touched: false,
            out_of_contact: 0.0,
            target_speed: 0.0,
            force_error: 0.0,
            speed_error: 0.0,
        }
    }

    fn reset(&mut self, config: &ArenaConfig<Self::Config>, scene: &mut Scene, rng: &mut Pcg64Mcg) {
        let task = &config.task;
        let torso = scene
            .torso()
            .expect("validated: the scan has a torso")
            .params()
            .clone();
        let period = 1.0 / config.controller.control_freq;
        let wanted = task.target_speed * config.horizon as f64 * period;
        let half = [
            torso.size[0] / 2.0 - task.edge_margin,
            torso.size[1] / 2.0 - task.edge_margin,
        ];
        let c = torso.center_xy;
        let (start, direction, length) = match task.trajectory {
            TrajectoryKind::Fixed => {
                let length = wanted.min(2.0 * half[1]);
                ([c[0], c[1] - length / 2.0], [0.0, 1.0], length)
            }
            TrajectoryKind::Random => {
                let angle = rng.random_range(0.0..std::f64::consts::TAU);
                let d = [angle.cos(), angle.sin()];
                // The longest segment along d that fits, capped at the wanted length.
                let fit_x = if d[0].abs() > 1e-9 {
                    2.0 * half[0] / d[0].abs()
                } else {
                    f64::INFINITY
                };
                let fit_y = if d[1].abs() > 1e-9 {
                    2.0 * half[1] / d[1].abs()
                } else {
                    f64::INFINITY
                };
                let length = wanted.min(fit_x).min(fit_y);
                let span = [
                    2.0 * half[0] - length * d[0].abs(),
                    2.0 * half[1] - length * d[1].abs(),
                ];
                let mut start = [0.0; 2];
                for k in 0..2 {
                    let lo = c[k] - half[k] + if d[k] < 0.0 { length * d[k].abs() } else { 0.0 };
                    start[k] = lo + rng.random_range(0.0..=1.0) * span[k].max(0.0);
                }
                (start, d, length)
            }
        };
        self.start = start;
        self.direction = direction;
        self.length = length;
        self.surface_z = torso.top_z();
        self.elapsed = 0.0;
        self.control_steps = 0;
        self.mean_speed = 0.0;
        self.force_average = 0.0;
        self.previous_force = 0.0;
        self.touched = false;
        self.out_of_contact = 0.0;
        self.target_speed = task.target_speed;
        self.force_error = -task.target_force;
        self.speed_error = -task.target_speed;

        let noise = config.randomization.probe_position_noise;
        let skin = scene
            .torso()
            .and_then(|t| t.skin_z(start[0], start[1]))
            .unwrap_or(self.surface_z);
        let position = [
            start[0] + gaussian(rng, noise),
            start[1] + gaussian(rng, noise),
            skin + task.start_height + gaussian(rng, noise).abs(),
        ];
        place_arm(
            scene,
            position,
            upright(),
            config.randomization.joint_noise,
            rng,
        );
    }

    fn after_physics_step(&mut self, scene: &Scene) {
        if scene.torso_wrench().in_contact() {
            self.touched = true;
        }
    }

    fn evaluate(
        &mut self,
        config: &ArenaConfig<Self::Config>,
        scene: &Scene,
        info: &mut [f32],
    ) -> Transition {
        let task = &config.task;
        let w = &task.reward;
        let period = 1.0 / config.controller.control_freq;
        self.elapsed += period;
        self.control_steps += 1;
        let tip = scene.tip_pose();
        let p = arr3(tip.translation);
        let (v, _) = scene.tip_velocity();
        let speed = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        self.mean_speed += (speed - self.mean_speed) / self.control_steps as f64;
        let force = scene.axial_contact_force();
        let alpha = task.force_smoothing;
        self.force_average = alpha * force + (1.0 - alpha) * self.force_average;
        let force_rate = (force - self.previous_force) / period;
        self.previous_force = force;
        let touching = scene.torso_wrench().in_contact();

        let target = self.target();
        let ex = (w.position_error * (p[0] - target[0])).powi(2);
        let ey = (w.position_error * (p[1] - target[1])).powi(2);
        let position_error = ex.hypot(ey);
        let angle = orientation_error(tip.rotation);
        let r_position = w.position_reward * (-position_error).exp();
        let r_orientation = w.orientation_reward * (-(w.orientation_error * angle)).exp();
        let r_speed = w.speed_reward
            * (-(w.speed_error * (self.mean_speed - task.target_speed)).powi(2)).exp();
        let (r_force, r_force_rate) = if touching {
            (
                w.force_reward
                    * (-(w.force_error * (self.force_average - task.target_force)).powi(2)).exp(),
                w.force_derivative_reward
                    * (-(w.force_derivative_error * force_rate).powi(2)).exp(),
            )
        } else {
            (0.0, 0.0)
        };

        if touching {
            self.out_of_contact = 0.0;
        } else if self.touched {
            self.out_of_contact += period;
        }
        let mut termination = ScanTermination::None;
        if task.early_termination {
            if near_joint_limit(scene) {
                termination = ScanTermination::JointLimit;
            } else if position_error > task.position_error_threshold {
                termination = ScanTermination::OffTrajectory;
            } else if touching && w.orientation_error * angle > task.orientation_error_threshold {
                termination = ScanTermination::Orientation;
            } else if self.touched && self.out_of_contact > task.contact_loss_grace {
                termination = ScanTermination::LostContact;
            }
        }
        self.force_error = self.force_average - task.target_force;
        self.speed_error = self.mean_speed - task.target_speed;
        let progress = if self.length > 0.0 {
            (task.target_speed * self.elapsed / self.length).min(1.0)
        } else {
            1.0
        };
        let success = progress >= 1.0
            && touching
            && position_error <= task.position_error_threshold
            && (self.force_average - task.target_force).abs() <= 1.0;
        let values = [
            r_position,
            r_orientation,
            r_speed,
            r_force,
            r_force_rate,
            force,
            self.force_average - task.target_force,
            speed,
            (p[0] - target[0]).hypot(p[1] - target[1]),
            angle,
            progress,
            f64::from(u8::from(touching)),
            f64::from(u8::from(success)),
            f64::from(termination as u8),
        ];
        for (slot, value) in info.iter_mut().zip(values) {
            *slot = value as f32;
        }
        Transition {
            reward: (r_position + r_orientation + r_speed + r_force + r_force_rate) as f32,
            terminated: termination != ScanTermination::None,
        }
    }

    fn task_errors(&self, scene: &Scene, out: &mut [f32]) {
        let tip = scene.tip_pose();
        let p = arr3(tip.translation);
        let target = self.target();
        out[0] = (p[0] - target[0]) as f32;
        out[1] = (p[1] - target[1]) as f32;
        out[2] = (p[2] - target[2]) as f32;
        out[3] = self.force_error as f32;
        out[4] = self.speed_error as f32;
        out[5] = orientation_error(tip.rotation) as f32;
        let moving = self.target_speed * self.elapsed < self.length;
        let v = if moving { self.target_speed } else { 0.0 };
        out[6] = (v * self.direction[0]) as f32;
        out[7] = (v * self.direction[1]) as f32;
    }

    fn focus(&self, scene: &Scene) -> [f64; 3] {
        scene.torso().map_or([0.0, 0.0, 0.8], |t| {
            let p = t.params();
            [p.center_xy[0], p.center_xy[1], p.top_z()]
        })
    }

    fn recording_labels(&self) -> (String, String) {
        ("sweep".into(), "slide".into())
    }
}

/// Angle between the probe's orientation and upright \[rad\].
fn orientation_error(rotation: Rotation) -> f64 {
    (upright() * rotation.inverse()).to_scaled_axis().length() as f64
}

/// A joint within 0.05 rad of a limit.
pub(crate) fn near_joint_limit(scene: &Scene) -> bool {
    let q = scene.arm().q(scene.world());
    scene
        .arm()
        .model()
        .joints
        .iter()
        .zip(q)
        .any(|(j, q)| q < j.lower + 0.05 || q > j.upper - 0.05)
}

/// Put the arm where the probe tip is at `position` with `rotation` (inverse kinematics
/// from the home pose), then add joint noise.
pub(crate) fn place_arm(
    scene: &mut Scene,
    position: [f64; 3],
    rotation: Rotation,
    joint_noise: f64,
    rng: &mut Pcg64Mcg,
) {
    let home = scene.arm().model().home.clone();
    let mut q = match solve_tip_pose(scene, position, rotation, &home) {
        Ok(q) => q,
        Err(e) => {
            tracing::debug!("start pose: {e}; starting from home");
            home
        }
    };
    if joint_noise > 0.0 {
        let joints = scene.arm().model().joints.clone();
        for (qk, j) in q.iter_mut().zip(&joints) {
            *qk = (*qk + gaussian(rng, joint_noise)).clamp(j.lower, j.upper);
        }
    }
    let zero = vec![0.0; q.len()];
    scene.set_arm_state(&q, &zero);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::envs::EnvFactory;
    use crate::envs::arena::{ArenaEnv, ArenaFactory};
    use crate::envs::env::{Env, EnvOutput};

    fn config(json: serde_json::Value) -> serde_json::Map<String, serde_json::Value> {
        json.as_object().unwrap().clone()
    }

    #[test]
    fn scripted_hybrid_sweep_holds_five_newtons() {
        let factory = ArenaFactory::<UltrasoundScan>::default();
        let spec = factory
            .spec(&config(serde_json::json!({
                "controller": {"kind": "hybrid_force_motion", "control_freq": 500.0},
            })))
            .unwrap();
        let mut env =
            ArenaEnv::<UltrasoundScan>::new(serde_json::from_value(spec.config.clone()).unwrap())
                .unwrap();
        let mut record = vec![0u8; spec.obs_record_bytes];
        let mut info = vec![0.0f32; spec.info_keys.len()];
        let errors = spec.field("task_errors").unwrap().offset / 4;
        let mut out = EnvOutput::new(&spec.observation, &mut record, &mut info);
        env.reset(Some(3), &mut out);
        let (mut within, mut contact, mut steps) = (0, 0, 0);
        for _ in 0..1000 {
            let obs: &[f32] = bytemuck::cast_slice(&record);
            let e = &obs[errors..errors + 8];
            let lead = 0.2;
            let rot = (upright() * env.scene().tip_pose().rotation.inverse()).to_scaled_axis();
            let action = [
                (-e[0] + lead * e[6]) / 0.05,
                (-e[1] + lead * e[7]) / 0.05,
                0.0,
                rot.x / 0.5,
                rot.y / 0.5,
                rot.z / 0.5,
            ];
            let mut out = EnvOutput::new(&spec.observation, &mut record, &mut info);
            let t = env.step(&action, &mut out);
            steps += 1;
            if info[11] > 0.5 {
                contact += 1;
                if (info[5] - 5.0).abs() <= 1.0 {
                    within += 1;
                }
            }
            assert!(!t.terminated, "terminated: {info:?}");
        }
        eprintln!("steps {steps} in contact {contact} within ±1 N {within}");
        assert!(contact > 500 && within as f64 >= 0.8 * contact as f64);
    }
}
