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
use super::observation::{declare_fields, write_fields};
use super::randomization::Draw;
use super::recorder::EpisodeRecorder;
use crate::envs::config::{EnvConfigError, parse_config};
use crate::envs::env::{Env, EnvOutput, Transition};
use crate::envs::registry::EnvFactory;
use crate::sim::controller::ArmController;
use crate::sim::scene::Scene;
use crate::sim::torso::Breathing;

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
    physics_steps: usize,
    recorder: Option<EpisodeRecorder>,
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
        let physics_steps = config.controller.physics_steps_per_action(scene.dt());
        let recorder = config
            .record
            .as_ref()
            .map(|r| EpisodeRecorder::new(&r.dir, T::Config::ID, r.episodes));
        Ok(Self {
            pristine: scene.clone(),
            scene,
            controller,
            task,
            rng: Pcg64Mcg::from_rng(&mut rand::rng()),
            physics_steps,
            recorder,
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
}

impl<T: Task> Env for ArenaEnv<T> {
    fn reset(&mut self, seed: Option<u64>, out: &mut EnvOutput<'_>) {
        if let Some(seed) = seed {
            self.rng = Pcg64Mcg::seed_from_u64(seed);
        }
        self.randomize();
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
        self.write_observation(out);
    }

    fn step(&mut self, action: &[f32], out: &mut EnvOutput<'_>) -> Transition {
        let action: Vec<f64> = action.iter().map(|&a| f64::from(a)).collect();
        let action = self.task.action(&self.scene, &action);
        self.controller.set_action(&self.scene, &action);
        for _ in 0..self.physics_steps {
            let tau = self.controller.torques(&mut self.scene);
            self.scene.step(&tau);
            self.task.after_physics_step(&self.scene);
            if let Some(recorder) = &mut self.recorder {
                recorder.sample(&self.scene);
            }
        }
        let transition = self.task.evaluate(&self.config, &self.scene, out.info());
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
            out,
        );
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
        let model = scene_params.robot.model();
        let dof = model.dof();
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
        for key in T::info_keys() {
            builder = builder.info_key(key);
        }
        let resolved = serde_json::to_value(&config).expect("config serializes");
        Ok(builder.config(resolved).build())
    }

    fn make(&self, spec: &EnvSpec) -> Box<dyn Env> {
        let config: ArenaConfig<T::Config> =
            serde_json::from_value(spec.config.clone()).expect("spec holds a validated config");
        Box::new(ArenaEnv::<T>::new(config).expect("validated config builds"))
    }
}
