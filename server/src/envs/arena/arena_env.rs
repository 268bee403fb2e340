//! [`ArenaEnv`]: the physics env every task shares — scene, controller, randomization,
//! observations, recording — with the task's logic plugged in through [`Task`].
//!
//! Step, in named stages: task-chosen action → controller sets its goal → physics steps
//! (each followed by the task's and the recorder's per-step hooks) → reward and
//! termination → observation.

use std::marker::PhantomData;

use echogym_protocol::EnvSpec;
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;

use super::config::{ArenaConfig, TaskConfig};
use super::observation::{HeldFrames, declare_fields, held_frames, write_fields};
use super::randomization::Draw;
use super::recorder::EpisodeRecorder;
use super::scene_state::{SceneStateSize, write_scene_state};
use crate::envs::config::{EnvConfigError, parse_config};
use crate::envs::env::{Env, EnvOutput, Transition};
use crate::envs::{EnvBuildError, EnvFactory};
use crate::sim::controller::ArmController;
use crate::sim::scene::Scene;
use crate::sim::torso::Breathing;
use crate::sim::ultrasound::{ImageStats, Imager, ImagingFrame};
use crate::sim::world::arr3;

/// Info keys the arena appends when the ultrasound image is on.
pub const ULTRASOUND_INFO_KEYS: [&str; 4] = [
    "us_coupled",
    "us_quality",
    "us_target_fraction",
    "us_target_cnr",
];

/// The probe's B-mode imager and its latest image.
struct Ultrasound {
    imager: Imager,
    image: Vec<u8>,
    stats: ImageStats,
    /// Index of the `ultrasound` field in the spec.
    field: usize,
}

impl Ultrasound {
    /// Image the scene's torso from the probe as it is now.
    fn render(&mut self, scene: &Scene) {
        let Some(torso) = scene.torso() else {
            return;
        };
        let tip = scene.tip_pose();
        let frame = ImagingFrame {
            origin: arr3(tip.translation),
            lateral: arr3(tip.rotation * rapier3d::prelude::Vector::Y),
            axis: arr3(tip.rotation * rapier3d::prelude::Vector::Z),
            half_width: scene.params().probe.face.half_width,
        };
        self.stats = self.imager.render(torso, &frame, &mut self.image);
    }

    fn write_info(&self, info: &mut [f32]) {
        let s = &self.stats;
        let values = [
            s.coupled_fraction,
            s.useful_fraction,
            s.target_fraction,
            s.target_cnr,
        ];
        for (slot, v) in info.iter_mut().zip(values) {
            *slot = v as f32;
        }
    }
}

/// A task's logic on top of the arena.
pub trait Task: Send + Sized + 'static {
    /// Its config.
    type Config: TaskConfig;

    /// Length of the `task_errors` observation.
    const TASK_ERRORS: usize;

    /// Names of the info values, in order.
    fn info_keys() -> &'static [&'static str];

    /// Build the task (once per env instance) and add what it needs to the pristine
    /// scene (e.g. the cube).
    fn new(config: &ArenaConfig<Self::Config>, scene: &mut Scene) -> Self;

    /// Start an episode: place the arm (and objects) in the freshly randomized `scene`.
    fn reset(&mut self, config: &ArenaConfig<Self::Config>, scene: &mut Scene, rng: &mut Pcg64Mcg);

    /// The action the controller applies (the policy's, or a scripted one).
    fn action(&mut self, _scene: &Scene, action: &[f64]) -> Vec<f64> {
        action.to_vec()
    }

    /// Called after every physics step.
    fn after_physics_step(&mut self, _scene: &Scene) {}

    /// Reward and termination after an env step; writes the info row.
    fn evaluate(
        &mut self,
        config: &ArenaConfig<Self::Config>,
        scene: &Scene,
        info: &mut [f32],
    ) -> Transition;

    /// The `task_errors` observation.
    fn task_errors(&self, scene: &Scene, out: &mut [f32]);

    /// Where cameras look: the work surface's centre [m, world].
    fn focus(&self, scene: &Scene) -> [f64; 3];

    /// Site and protocol names for recordings.
    fn recording_labels(&self) -> (String, String);
}

/// A physics env: the arena plus task `T`.
pub struct ArenaEnv<T: Task> {
    config: ArenaConfig<T::Config>,
    pristine: Scene,
    scene: Scene,
    controller: ArmController,
    task: T,
    rng: Pcg64Mcg,
    recorder: Option<EpisodeRecorder>,
    ultrasound: Option<Ultrasound>,
    /// Index of `scene_colliders` when `scene_state` is on.
    scene_field: Option<usize>,
    /// Steps since the reset (cameras with `every > 1` render on its multiples).
    frame: u64,
    held: HeldFrames,
}

impl<T: Task> ArenaEnv<T> {
    /// Build the env (validated config).
    pub fn new(config: ArenaConfig<T::Config>) -> Result<Self, String> {
        let mut scene = Scene::new(config.scene_params()).map_err(|e| e.to_string())?;
        let task = T::new(&config, &mut scene);
        // Build the broad phase once here: every reset clones this scene, and an empty
        // broad phase would be rebuilt from scratch at each episode's first step.
        scene.world_mut().update_queries();
        let controller = ArmController::new(config.controller.clone(), &scene);
        let recorder = config
            .record
            .as_ref()
            .map(|r| {
                let dir = crate::recordings::root::resolve(&r.dir)
                    .map_err(|m| format!("record.dir: {m}"))?;
                Ok::<_, String>(EpisodeRecorder::new(&dir, T::Config::ID, r.episodes))
            })
            .transpose()?;
        let camera_fields: usize = config
            .cameras
            .iter()
            .map(|c| usize::from(c.rgb) + usize::from(c.depth))
            .sum();
        let ultrasound = match (&config.ultrasound, &config.torso) {
            (Some(us), Some(torso)) => Some(Ultrasound {
                imager: Imager::new(us.clone(), torso.size),
                image: vec![0; us.rows * us.lines],
                stats: ImageStats::default(),
                field: config.observations.len() + camera_fields,
            }),
            _ => None,
        };
        let scene_field = config
            .scene_state
            .then(|| config.observations.len() + camera_fields + usize::from(ultrasound.is_some()));
        Ok(Self {
            scene_field,
            frame: 0,
            held: held_frames(&config.cameras),
            pristine: scene.clone(),
            scene,
            controller,
            task,
            rng: Pcg64Mcg::from_rng(&mut rand::rng()),
            recorder,
            ultrasound,
            config,
        })
    }

    /// The scene (for tests and tools).
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Restore the pristine scene and apply this episode's randomization.
    fn randomize(&mut self) {
        let c = &self.config;
        let draw: Draw = c.randomization.draw(
            &mut self.rng,
            c.torso.as_ref(),
            c.breathing.as_ref(),
            c.probe.mass,
            &c.ft_sensor,
        );
        self.scene = self.pristine.clone();
        // Validated ranges keep the torso valid; a failure keeps the nominal one.
        if let Some(torso) = draw.torso
            && Some(&torso) != self.scene.params().torso.as_ref()
            && let Err(e) = self.scene.replace_torso(torso)
        {
            tracing::debug!("randomized torso rejected: {e}");
        }
        if let Some(breathing) = draw.breathing {
            let law = self
                .scene
                .torso()
                .map(|t| Breathing::new(breathing, t, draw.noise_seed));
            if let (Some(Ok(law)), Some(torso)) = (law, self.scene.torso_mut()) {
                let u = law.equilibrium();
                torso.set_state(&u, &vec![0.0; u.len()]);
                torso.add_law(Box::new(law));
            }
        }
        self.scene.set_probe_mass(draw.probe_mass);
        self.scene.set_ft_sensor(draw.ft_sensor, draw.noise_seed);
    }

    fn write_observation(&mut self, out: &mut EnvOutput<'_>) {
        if !self.config.cameras.is_empty() {
            self.scene.sync_torso_collider();
        }
        self.observe(out);
    }

    /// Form this step's ultrasound image (before the reward, which may use it).
    /// Form the ultrasound image on reset (frame 0) and every `every_n_steps` steps.
    fn image(&mut self) {
        let every = self
            .config
            .ultrasound
            .as_ref()
            .map_or(1, |c| c.every_n_steps as u64);
        if let Some(us) = &mut self.ultrasound
            && self.frame.is_multiple_of(every)
        {
            us.render(&self.scene);
        }
    }
}

impl<T: Task> Env for ArenaEnv<T> {
    fn reset(&mut self, seed: Option<u64>, out: &mut EnvOutput<'_>) {
        if let Some(seed) = seed {
            self.rng = Pcg64Mcg::seed_from_u64(seed);
        }
        self.randomize();
        self.frame = 0;
        self.task
            .reset(&self.config, &mut self.scene, &mut self.rng);
        self.controller = ArmController::new(self.config.controller.clone(), &self.scene);
        out.info().fill(0.0);
        if let Some(recorder) = &mut self.recorder {
            let (site, protocol) = self.task.recording_labels();
            recorder.begin(&self.scene, &site, &protocol);
        }
        if !self.config.cameras.is_empty() {
            // Bodies were rebuilt and teleported: let rays see where they are now.
            self.scene.sync_torso_collider();
            self.scene.world_mut().update_queries();
        }
        self.image();
        self.write_observation(out);
    }

    fn step(&mut self, action: &[f32], out: &mut EnvOutput<'_>) -> Transition {
        self.frame += 1;
        let action: Vec<f64> = action.iter().map(|&a| f64::from(a)).collect();
        let action = self.task.action(&self.scene, &action);
        let (task, recorder) = (&mut self.task, &mut self.recorder);
        self.controller
            .act_observed(&mut self.scene, &action, |scene| {
                task.after_physics_step(scene);
                if let Some(recorder) = recorder {
                    recorder.sample(scene);
                }
            });
        self.image();
        let mut transition = self.task.evaluate(&self.config, &self.scene, out.info());
        if let (Some(us), Some(c)) = (&self.ultrasound, &self.config.ultrasound) {
            transition.reward += (c.reward_weight * us.stats.useful_fraction) as f32;
        }
        self.write_observation(out);
        transition
    }

    fn observe(&self, out: &mut EnvOutput<'_>) {
        let mut errors = vec![0.0f32; T::TASK_ERRORS];
        self.task.task_errors(&self.scene, &mut errors);
        let focus = self.task.focus(&self.scene);
        write_fields(
            &self.scene,
            &self.config.observations,
            &self.config.cameras,
            focus,
            &errors,
            self.frame,
            &self.held,
            out,
        );
        if let Some(us) = &self.ultrasound {
            out.u8_field(us.field).copy_from_slice(&us.image);
            us.write_info(&mut out.info()[T::info_keys().len()..]);
        }
        if let Some(first) = self.scene_field {
            write_scene_state(&self.scene, first, out);
        }
    }
}

/// The registry entry of task `T`.
pub struct ArenaFactory<T: Task>(PhantomData<fn() -> T>);

impl<T: Task> Default for ArenaFactory<T> {
    fn default() -> Self {
        Self(PhantomData)
    }
}

impl<T: Task> EnvFactory for ArenaFactory<T> {
    fn id(&self) -> &'static str {
        T::Config::ID
    }

    fn description(&self) -> &'static str {
        T::Config::DESCRIPTION
    }

    fn spec(
        &self,
        config: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<EnvSpec, EnvConfigError> {
        let id = T::Config::ID;
        let config: ArenaConfig<T::Config> = parse_config(id, config)?;
        config.validate()?;
        let scene_params = config.scene_params();
        let dof = config
            .robot
            .model()
            .map_err(|e| EnvConfigError::Invalid {
                env_id: id.to_owned(),
                key: "robot",
                message: e.to_string(),
            })?
            .dof();
        let particles = match &config.torso {
            Some(t) => {
                crate::sim::torso::ShellLayout::new(t.size, t.center_xy, t.bottom_z, t.spacing)
                    .len()
            }
            None => 0,
        };
        let dt = scene_params.world.dt;
        let steps = config.controller.physics_steps_per_action(dt);
        let mut builder = EnvSpec::builder(id, config.controller.action_size(dof))
            .max_episode_steps(Some(config.horizon))
            .dt_s(dt * steps as f64);
        builder = declare_fields(
            builder,
            &config.observations,
            &config.cameras,
            dof,
            particles,
            T::TASK_ERRORS,
        );
        if let Some(us) = &config.ultrasound {
            builder = builder.field(
                "ultrasound",
                echogym_protocol::DType::Uint8,
                &[us.rows, us.lines],
                Some(0.0),
                Some(255.0),
            );
        }
        if config.scene_state {
            // Build the scene once (task objects included) to count its colliders.
            let mut scene =
                Scene::new(scene_params.clone()).map_err(|e| EnvConfigError::Invalid {
                    env_id: id.to_owned(),
                    key: "scene_state",
                    message: e.to_string(),
                })?;
            T::new(&config, &mut scene);
            let largest = config.randomization.torso_scale[1];
            builder = SceneStateSize::of(&scene, config.torso.as_ref(), largest).declare(builder);
        }
        for key in T::info_keys() {
            builder = builder.info_key(key);
        }
        if config.ultrasound.is_some() {
            for key in ULTRASOUND_INFO_KEYS {
                builder = builder.info_key(key);
            }
        }
        // Written by the batch, not the env (1 on a step truncated because the physics
        // went non-finite); `build` appends `env_error` after it.
        builder = builder.info_key(crate::envs::PHYSICS_ERROR_KEY);
        let resolved = serde_json::to_value(&config).expect("config serializes");
        Ok(builder.config(resolved).build())
    }

    fn make(&self, spec: &EnvSpec) -> Result<Box<dyn Env>, EnvBuildError> {
        let error = |e: &dyn std::fmt::Display| EnvBuildError::new(T::Config::ID, e);
        let config: ArenaConfig<T::Config> =
            serde_json::from_value(spec.config.clone()).map_err(|e| error(&e))?;
        Ok(Box::new(ArenaEnv::<T>::new(config).map_err(|e| error(&e))?))
    }
}
