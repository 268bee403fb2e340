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

    /// Build one env from a spec this factory resolved.
    fn make(&self, spec: &EnvSpec) -> Box<dyn Env>;
}
