//! What the registry holds per env id: a factory that validates configs and builds envs.

use echogym_protocol::EnvSpec;

use super::config::EnvConfigError;
use super::env::Env;

/// Builds envs of one id.
pub trait EnvFactory: Send + Sync {
    /// Versioned id, e.g. `echogym/Null-v0`.
    fn id(&self) -> &'static str;

    /// One-line description.
    fn description(&self) -> &'static str;

    /// Validate `config` and resolve the spec (defaults filled into `spec.config`).
    fn spec(
        &self,
        config: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<EnvSpec, EnvConfigError>;

    /// Build one env from a spec this factory resolved. A spec that validated can
    /// still fail to build (e.g. a robot file that vanished): the error says why.
    fn make(&self, spec: &EnvSpec) -> Result<Box<dyn Env>, EnvBuildError>;
}

/// An env could not be built from a resolved spec.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("cannot build {env_id}: {message}")]
pub struct EnvBuildError {
    /// The env id.
    pub env_id: String,
    /// Why.
    pub message: String,
}

impl EnvBuildError {
    /// An error of `env_id` saying `message`.
    pub fn new(env_id: &str, message: impl std::fmt::Display) -> Self {
        Self {
            env_id: env_id.to_owned(),
            message: message.to_string(),
        }
    }
}
