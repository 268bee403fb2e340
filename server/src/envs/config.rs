//! Env config parsing: unknown keys and out-of-range values are errors naming the key.

use serde::de::DeserializeOwned;

/// Why an env config was rejected.
#[derive(Debug, thiserror::Error, Clone, PartialEq, Eq)]
pub enum EnvConfigError {
    /// A key is unknown or a value has the wrong type (serde's message names the key).
    #[error("invalid config for {env_id}: {message}")]
    Malformed {
        /// The env id.
        env_id: String,
        /// What serde said.
        message: String,
    },
    /// A value is outside its allowed range.
    #[error("invalid config for {env_id}: `{key}` must be {expected}, got {got}")]
    OutOfRange {
        /// The env id.
        env_id: String,
        /// The offending key.
        key: &'static str,
        /// The allowed range, in words.
        expected: String,
        /// The value given.
        got: String,
    },
    /// A value is invalid for a reason stated in words.
    #[error("invalid config for {env_id}: `{key}`: {message}")]
    Invalid {
        /// The env id.
        env_id: String,
        /// The offending key.
        key: &'static str,
        /// What is wrong.
        message: String,
    },
}

/// Parse a JSON object into an env's config struct (which must deny unknown fields).
pub fn parse_config<T: DeserializeOwned>(
    env_id: &str,
    config: &serde_json::Map<String, serde_json::Value>,
) -> Result<T, EnvConfigError> {
    serde_json::from_value(serde_json::Value::Object(config.clone())).map_err(|e| {
        EnvConfigError::Malformed {
            env_id: env_id.to_owned(),
            message: e.to_string(),
        }
    })
}

/// Check `lo <= value <= hi` for a config key.
pub(crate) fn check_range<T: PartialOrd + std::fmt::Display>(
    env_id: &str,
    key: &'static str,
    value: T,
    lo: T,
    hi: T,
) -> Result<(), EnvConfigError> {
    if value >= lo && value <= hi {
        Ok(())
    } else {
        Err(EnvConfigError::OutOfRange {
            env_id: env_id.to_owned(),
            key,
            expected: format!("between {lo} and {hi}"),
            got: value.to_string(),
        })
    }
}
