//! Environments: what a step does, what it observes, how it is configured.
//!
//! An env writes its observation straight into the shared-memory record it is handed
//! ([`EnvOutput`]); the pool and transport never copy observations.

pub mod arena;
pub mod calibration_press;
mod config;
mod env;
mod factory;
mod faulty;
mod null;
pub mod push_cube;
mod registry;
pub mod ultrasound_scan;

pub use config::{EnvConfigError, parse_config};
pub use env::{Env, EnvOutput, PHYSICS_ERROR_KEY, Transition};
pub use factory::{EnvBuildError, EnvFactory};
pub use faulty::{FAULTY_ENV_ID, FaultyConfig, FaultyEnvFactory, PanicIn};
pub use null::{NULL_ENV_ID, NullConfig, NullEnvFactory};
pub use registry::{EnvRegistry, UnknownEnv};
