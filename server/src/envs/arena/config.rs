//! [`ArenaConfig`]: what every physics env shares (robot, controller, torso, probe,
//! sensor, breathing, randomization, observations, cameras, horizon, recording), with
//! the task's own settings nested under `task`.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use super::observation::{CameraConfig, Observation};
use super::randomization::Randomization;
use crate::envs::config::{EnvConfigError, check_range};
use crate::sim::controller::ControllerConfig;
use crate::sim::ft_sensor::FtSensorParams;
use crate::sim::probe::ProbeParams;
use crate::sim::robot::RobotConfig;
use crate::sim::scene::SceneParams;

/// Most cameras one env may render.
pub const MAX_CAMERAS: usize = 8;
/// Most pixels one env's cameras may render per step, over all of them (four 1024²
/// views): a bound on what one env's config can make the server allocate and cast.
pub const MAX_CAMERA_PIXELS: usize = 4 * 1024 * 1024;
use crate::sim::torso::{BreathingParams, TorsoParams};
use crate::sim::ultrasound::UltrasoundConfig;

/// A task's own settings and identity.
pub trait TaskConfig:
    Clone + std::fmt::Debug + PartialEq + Serialize + DeserializeOwned + Send + Sync + 'static
{
    /// The registered id.
    const ID: &'static str;
    /// One-line description.
    const DESCRIPTION: &'static str;

    /// The arena defaults of this task (its controller rate, observations, torso...).
    fn arena_default() -> ArenaConfig<Self>;

    /// Check the task's ranges; `Err` names the key (prefixed `task.`).
    fn validate(&self, arena: &ArenaConfig<Self>) -> Result<(), EnvConfigError>;
}

/// Where and how much to record (see [`crate::recordings`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordConfig {
    /// Folder receiving one dataset per env instance
    /// (`<dir>/<task>-<pid>-<instance>/dataset.json` + one CSV per episode), inside the
    /// server's recordings root (see [`crate::recordings::root`]).
    pub dir: std::path::PathBuf,
    /// Episodes recorded per env instance (later ones are not). Default 100.
    #[serde(default = "default_record_episodes")]
    pub episodes: usize,
}

fn default_record_episodes() -> usize {
    100
}

/// The full config of a physics env; unknown keys are errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default, bound = "T: TaskConfig")]
pub struct ArenaConfig<T: TaskConfig> {
    /// Arm: `"panda"`, `"ur5e"`, or a URDF file
    /// `{urdf, tool_link, tool_offset, tool_rpy, home}` ([`RobotConfig`]).
    pub robot: RobotConfig,
    /// Action interface (controller kind, control frequency, limits, gains).
    pub controller: ControllerConfig,
    /// Steps per episode before truncation.
    pub horizon: u64,
    /// The soft torso at rest (`null`: none).
    pub torso: Option<TorsoParams>,
    /// The probe.
    pub probe: ProbeParams,
    /// Force-torque sensor imperfections (before randomization).
    pub ft_sensor: FtSensorParams,
    /// Breathing motion of the torso's top (`null`: none); its rate and amplitude are
    /// drawn per episode from `randomization`.
    pub breathing: Option<BreathingParams>,
    /// Per-episode randomization ranges.
    pub randomization: Randomization,
    /// Observation fields, in order.
    pub observations: Vec<Observation>,
    /// Cameras (each adds `<name>_rgb` and/or `<name>_depth` fields).
    pub cameras: Vec<CameraConfig>,
    /// B-mode ultrasound image from the probe (`null`: off); adds the `ultrasound`
    /// field (uint8 `[rows, lines]`) and the `us_*` info values.
    pub ultrasound: Option<UltrasoundConfig>,
    /// Record episodes (`null`: off).
    pub record: Option<RecordConfig>,
    /// Deliver the scene's state for viewers (`scene_colliders`, `torso_vertices`,
    /// `torso_triangles`, `scene_contact` after every other field); off by default, and
    /// then it costs nothing.
    pub scene_state: bool,
    /// The task's own settings.
    pub task: T,
}

impl<T: TaskConfig> Default for ArenaConfig<T> {
    fn default() -> Self {
        T::arena_default()
    }
}

impl<T: TaskConfig> ArenaConfig<T> {
    /// Defaults shared by every task (Panda, 20 Hz OSC_POSE, the seed's torso, no
    /// breathing, no cameras); tasks override from here.
    pub fn base(task: T) -> Self {
        Self {
            robot: RobotConfig::default(),
            controller: ControllerConfig::default(),
            horizon: 500,
            torso: Some(TorsoParams::default()),
            probe: ProbeParams::default(),
            ft_sensor: FtSensorParams::default(),
            breathing: None,
            randomization: Randomization::default(),
            observations: vec![
                Observation::JointPos,
                Observation::JointVel,
                Observation::ProbePose,
                Observation::ProbeVel,
                Observation::Ft,
                Observation::Contact,
                Observation::TaskErrors,
            ],
            cameras: Vec::new(),
            ultrasound: None,
            record: None,
            scene_state: false,
            task,
        }
    }

    /// Check every range; the error names the key.
    pub fn validate(&self) -> Result<(), EnvConfigError> {
        let id = T::ID;
        let wrap = |key: &'static str, message: String| EnvConfigError::Invalid {
            env_id: id.to_owned(),
            key,
            message,
        };
        check_range(id, "horizon", self.horizon, 1, 10_000_000)?;
        self.robot
            .model()
            .map_err(|e| wrap("robot", e.to_string()))?;
        let scene = self.scene_params();
        self.controller
            .validate(scene.world.dt)
            .map_err(|e| wrap("controller", e.to_string()))?;
        if let Some(torso) = &self.torso {
            torso.validate().map_err(|e| wrap("torso", e.to_string()))?;
        }
        self.probe
            .validate()
            .map_err(|e| wrap("probe", e.to_string()))?;
        self.ft_sensor
            .validate()
            .map_err(|e| wrap("ft_sensor", e.to_string()))?;
        if let Some(b) = &self.breathing {
            b.validate().map_err(|e| wrap("breathing", e.to_string()))?;
            if self.torso.is_none() {
                return Err(wrap("breathing", "only with a torso".into()));
            }
        }
        self.randomization.validate(id)?;
        if self.cameras.len() > MAX_CAMERAS {
            return Err(wrap(
                "cameras",
                format!(
                    "at most {MAX_CAMERAS} cameras per env ({} given)",
                    self.cameras.len()
                ),
            ));
        }
        let pixels: usize = self.cameras.iter().map(|c| c.width * c.height).sum();
        if pixels > MAX_CAMERA_PIXELS {
            return Err(wrap(
                "cameras",
                format!(
                    "at most {MAX_CAMERA_PIXELS} pixels per env over all cameras ({pixels} given): fewer or smaller cameras"
                ),
            ));
        }
        let mut names = std::collections::HashSet::new();
        for cam in &self.cameras {
            cam.validate(id)?;
            if !names.insert(cam.name.clone()) {
                return Err(wrap(
                    "cameras",
                    format!("unique names ({:?} twice)", cam.name),
                ));
            }
        }
        if self.observations.contains(&Observation::TorsoParticles) && self.torso.is_none() {
            return Err(wrap(
                "observations",
                "without `torso_particles` when there is no torso".into(),
            ));
        }
        if let Some(us) = &self.ultrasound {
            us.validate(2.0 * self.probe.face.half_length)
                .map_err(|e| wrap(e.key, e.message))?;
            if self.torso.is_none() {
                return Err(wrap("ultrasound", "only with a torso".into()));
            }
        }
        if let Some(record) = &self.record {
            check_range(id, "record.episodes", record.episodes, 1, 1_000_000)?;
            crate::recordings::root::resolve(&record.dir).map_err(|m| wrap("record.dir", m))?;
        }
        self.task.validate(self)
    }

    /// The scene before randomization.
    pub fn scene_params(&self) -> SceneParams {
        SceneParams {
            robot: self.robot.clone(),
            probe: self.probe.clone(),
            torso: self.torso.clone(),
            ft_sensor: self.ft_sensor.clone(),
            ..SceneParams::default()
        }
    }
}
