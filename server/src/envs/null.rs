//! `echogym/Null-v0`: no physics, for transport tests and benchmarks.
//!
//! Observation `obs` (float32, `obs_size`):
//! - `obs[0]`: steps taken in the episode (0 after reset);
//! - `obs[1..1 + n]`: the last action, `n = min(action_size, obs_size - 2)` (zeros after reset);
//! - `obs[obs_size - 1]`: a uniform draw in `[0, 1)` from the env's seeded generator;
//! - the rest: zero.
//!
//! Reward: the first action element. Never terminates; truncates at `max_episode_steps`.
//! `step_cost_us` burns that much CPU per step to stand in for physics in benchmarks.

use std::time::{Duration, Instant};

use echogym_protocol::EnvSpec;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};

use super::config::{EnvConfigError, check_range, parse_config};
use super::env::{Env, EnvOutput, Transition};
use super::factory::{EnvBuildError, EnvFactory};

/// The registered id.
pub const NULL_ENV_ID: &str = "echogym/Null-v0";

/// Config of `echogym/Null-v0`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct NullConfig {
    /// Observation length (float32 elements). Default 64, range 2..=1,048,576.
    pub obs_size: usize,
    /// Action length. Default 7 (a 7-DoF arm), range 1..=4096.
    pub action_size: usize,
    /// CPU time burnt per step, µs (0 = none). Default 0, range 0..=1,000,000.
    pub step_cost_us: f64,
    /// Truncation horizon in steps (`null` = never). Default 1000.
    pub max_episode_steps: Option<u64>,
}

impl Default for NullConfig {
    fn default() -> Self {
        Self {
            obs_size: 64,
            action_size: 7,
            step_cost_us: 0.0,
            max_episode_steps: Some(1000),
        }
    }
}

impl NullConfig {
    fn validate(&self) -> Result<(), EnvConfigError> {
        check_range(NULL_ENV_ID, "obs_size", self.obs_size, 2, 1 << 20)?;
        check_range(NULL_ENV_ID, "action_size", self.action_size, 1, 4096)?;
        check_range(NULL_ENV_ID, "step_cost_us", self.step_cost_us, 0.0, 1e6)?;
        if let Some(steps) = self.max_episode_steps {
            check_range(NULL_ENV_ID, "max_episode_steps", steps, 1, u64::MAX)?;
        }
        Ok(())
    }
}

/// Factory of `echogym/Null-v0`.
pub struct NullEnvFactory;

impl EnvFactory for NullEnvFactory {
    fn id(&self) -> &'static str {
        NULL_ENV_ID
    }

    fn description(&self) -> &'static str {
        "no physics: echoes the action and a step counter (transport tests, benchmarks)"
    }

    fn spec(
        &self,
        config: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<EnvSpec, EnvConfigError> {
        let config: NullConfig = parse_config(NULL_ENV_ID, config)?;
        config.validate()?;
        let resolved = serde_json::to_value(&config).expect("config serializes");
        Ok(EnvSpec::builder(NULL_ENV_ID, config.action_size)
            .f32_field("obs", &[config.obs_size])
            .info_key("episode_step")
            .max_episode_steps(config.max_episode_steps)
            .config(resolved)
            .build())
    }

    fn make(&self, spec: &EnvSpec) -> Result<Box<dyn Env>, EnvBuildError> {
        let config: NullConfig = serde_json::from_value(spec.config.clone())
            .map_err(|e| EnvBuildError::new(NULL_ENV_ID, e))?;
        Ok(Box::new(NullEnv::new(config)))
    }
}

struct NullEnv {
    config: NullConfig,
    rng: Pcg64Mcg,
    episode_step: u64,
    last_action: Vec<f32>,
    last_draw: f32,
}

impl NullEnv {
    fn new(config: NullConfig) -> Self {
        let action_size = config.action_size;
        Self {
            config,
            rng: Pcg64Mcg::from_rng(&mut rand::rng()),
            episode_step: 0,
            last_action: vec![0.0; action_size],
            last_draw: 0.0,
        }
    }

    fn burn(&self) {
        if self.config.step_cost_us > 0.0 {
            let until = Instant::now() + Duration::from_secs_f64(self.config.step_cost_us * 1e-6);
            while Instant::now() < until {
                std::hint::spin_loop();
            }
        }
    }
}

impl Env for NullEnv {
    fn reset(&mut self, seed: Option<u64>, out: &mut EnvOutput<'_>) {
        if let Some(seed) = seed {
            self.rng = Pcg64Mcg::seed_from_u64(seed);
        }
        self.episode_step = 0;
        self.last_action.fill(0.0);
        self.last_draw = self.rng.random();
        self.observe(out);
    }

    fn step(&mut self, action: &[f32], out: &mut EnvOutput<'_>) -> Transition {
        self.burn();
        self.episode_step += 1;
        self.last_action.copy_from_slice(action);
        self.last_draw = self.rng.random();
        self.observe(out);
        Transition {
            reward: action[0],
            terminated: false,
        }
    }

    fn observe(&self, out: &mut EnvOutput<'_>) {
        let obs = out.f32_field(0);
        obs.fill(0.0);
        obs[0] = self.episode_step as f32;
        let n = self.last_action.len().min(obs.len() - 2);
        obs[1..1 + n].copy_from_slice(&self.last_action[..n]);
        let last = obs.len() - 1;
        obs[last] = self.last_draw;
        out.info()[0] = self.episode_step as f32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(seed: u64) -> Vec<f32> {
        let spec = NullEnvFactory.spec(&serde_json::Map::new()).unwrap();
        let mut env = NullEnvFactory.make(&spec).unwrap();
        let mut record = vec![0u8; spec.obs_record_bytes];
        let mut info = vec![0.0f32; 1];
        let mut out = EnvOutput::new(&spec.observation, &mut record, &mut info);
        env.reset(Some(seed), &mut out);
        let t = env.step(&[0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0], &mut out);
        assert_eq!(t.reward, 0.5);
        bytemuck::cast_slice::<u8, f32>(&record).to_vec()
    }

    #[test]
    fn echoes_action_and_counts_steps() {
        let obs = run(1);
        assert_eq!(obs[0], 1.0);
        assert_eq!(&obs[1..8], &[0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert!((0.0..1.0).contains(&obs[63]));
    }

    #[test]
    fn same_seed_same_draws() {
        assert_eq!(run(7), run(7));
        assert_ne!(run(7)[63], run(8)[63]);
    }

    #[test]
    fn rejects_unknown_keys_and_bad_ranges() {
        let mut config = serde_json::Map::new();
        config.insert("obs_sise".into(), 3.into());
        let err = NullEnvFactory.spec(&config).unwrap_err().to_string();
        assert!(err.contains("obs_sise"), "{err}");
        let mut config = serde_json::Map::new();
        config.insert("obs_size".into(), 0.into());
        let err = NullEnvFactory.spec(&config).unwrap_err().to_string();
        assert!(err.contains("`obs_size`"), "{err}");
    }
}
