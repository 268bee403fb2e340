//! `echogym/Faulty-v0`: an env that panics where it is told to, so tests can check that
//! no env fault reaches the daemon. Registered only by `echogym serve --fault-injection`
//! (a hidden flag for tests); never in a default registry.
//!
//! Observation `obs` (float32, 2): steps in the episode and the env's index in its batch.
//! Config `panic_in`: `none` | `make` | `reset` | `step` | `drop`; `env_index`: which env
//! misbehaves, counted over every Faulty env this server built, from 0 (default 0);
//! `at_step`: the step that panics (default 1); `stall_ms`: that env sleeps this long in
//! every step (a step that outlives the client's deadline); `nan_at_step`: that env's
//! observation is NaN at this step of each episode (a physics blow-up; 0: never). It
//! declares the `physics_error` info key.

use std::sync::atomic::{AtomicUsize, Ordering};

use echogym_protocol::EnvSpec;
use serde::{Deserialize, Serialize};

use super::config::{EnvConfigError, parse_config};
use super::env::{Env, EnvOutput, Transition};
use super::factory::{EnvBuildError, EnvFactory};

/// The registered id.
pub const FAULTY_ENV_ID: &str = "echogym/Faulty-v0";

/// Where the faulty env panics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum PanicIn {
    /// Nowhere.
    #[default]
    None,
    /// While being built.
    Make,
    /// In every reset.
    Reset,
    /// In step `at_step` of each episode.
    Step,
    /// While being dropped.
    Drop,
}

/// Config of `echogym/Faulty-v0`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
#[serde(deny_unknown_fields, default)]
pub struct FaultyConfig {
    /// Where to panic.
    pub panic_in: PanicIn,
    /// Which env panics: the nth Faulty env this server builds, from 0.
    pub env_index: usize,
    /// The episode step that panics (`panic_in = "step"`); 0 counts as 1.
    pub at_step: u64,
    /// Milliseconds the chosen env sleeps in every step.
    pub stall_ms: u64,
    /// The episode step at which the chosen env's observation is NaN (0: never).
    pub nan_at_step: u64,
}

/// Factory of `echogym/Faulty-v0`; numbers the envs it builds.
#[derive(Default)]
pub struct FaultyEnvFactory {
    built: AtomicUsize,
}

impl EnvFactory for FaultyEnvFactory {
    fn id(&self) -> &'static str {
        FAULTY_ENV_ID
    }

    fn description(&self) -> &'static str {
        "fault injection for tests: panics in make, reset, step or drop; NaN observations"
    }

    fn spec(
        &self,
        config: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<EnvSpec, EnvConfigError> {
        let config: FaultyConfig = parse_config(FAULTY_ENV_ID, config)?;
        let resolved = serde_json::to_value(&config).map_err(|e| EnvConfigError::Malformed {
            env_id: FAULTY_ENV_ID.to_owned(),
            message: e.to_string(),
        })?;
        Ok(EnvSpec::builder(FAULTY_ENV_ID, 1)
            .f32_field("obs", &[2])
            .info_key(super::env::PHYSICS_ERROR_KEY)
            .max_episode_steps(Some(100))
            .config(resolved)
            .build())
    }

    fn make(&self, spec: &EnvSpec) -> Result<Box<dyn Env>, EnvBuildError> {
        let config: FaultyConfig = serde_json::from_value(spec.config.clone())
            .map_err(|e| EnvBuildError::new(FAULTY_ENV_ID, e))?;
        let index = self.built.fetch_add(1, Ordering::SeqCst);
        let faulty = index == config.env_index;
        if faulty && config.panic_in == PanicIn::Make {
            panic!("injected fault: make of env {index}");
        }
        Ok(Box::new(FaultyEnv {
            panic_in: if faulty {
                config.panic_in
            } else {
                PanicIn::None
            },
            at_step: config.at_step.max(1),
            stall: std::time::Duration::from_millis(if faulty { config.stall_ms } else { 0 }),
            nan_at_step: if faulty { config.nan_at_step } else { 0 },
            index,
            step: 0,
        }))
    }
}

struct FaultyEnv {
    panic_in: PanicIn,
    at_step: u64,
    stall: std::time::Duration,
    nan_at_step: u64,
    index: usize,
    step: u64,
}

impl Env for FaultyEnv {
    fn reset(&mut self, _seed: Option<u64>, out: &mut EnvOutput<'_>) {
        if self.panic_in == PanicIn::Reset {
            panic!("injected fault: reset of env {}", self.index);
        }
        self.step = 0;
        self.observe(out);
    }

    fn step(&mut self, _action: &[f32], out: &mut EnvOutput<'_>) -> Transition {
        self.step += 1;
        std::thread::sleep(self.stall);
        if self.panic_in == PanicIn::Step && self.step == self.at_step {
            panic!("injected fault: step {} of env {}", self.step, self.index);
        }
        self.observe(out);
        if self.step == self.nan_at_step {
            out.f32_field(0)[0] = f32::NAN;
        }
        Transition {
            reward: 0.0,
            terminated: false,
        }
    }

    fn observe(&self, out: &mut EnvOutput<'_>) {
        let obs = out.f32_field(0);
        obs[0] = self.step as f32;
        obs[1] = self.index as f32;
    }
}

impl Drop for FaultyEnv {
    fn drop(&mut self) {
        if self.panic_in == PanicIn::Drop && !std::thread::panicking() {
            panic!("injected fault: drop of env {}", self.index);
        }
    }
}
