//! The env spec: what a client learns about an env at attach time.
//!
//! Built by the server's env registry, sent once as JSON, and used by the client to
//! build gymnasium spaces / torchrl specs and numpy views onto the observation sample.

use serde::{Deserialize, Serialize};

/// Element type of an observation field.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DType {
    /// IEEE 754 single precision (numpy `float32`).
    Float32,
    /// Unsigned byte (numpy `uint8`), used for images.
    Uint8,
    /// Signed 32-bit integer (numpy `int32`).
    Int32,
}

impl DType {
    /// Size of one element in bytes.
    pub const fn size(self) -> usize {
        match self {
            Self::Float32 | Self::Int32 => 4,
            Self::Uint8 => 1,
        }
    }

    /// The numpy dtype name.
    pub const fn numpy_name(self) -> &'static str {
        match self {
            Self::Float32 => "float32",
            Self::Uint8 => "uint8",
            Self::Int32 => "int32",
        }
    }
}

/// One named field of an env's observation record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObsField {
    /// Field name, unique within the spec (the key of the gymnasium `Dict` space).
    pub name: String,
    /// Element type.
    pub dtype: DType,
    /// Shape of one env's field (C order), e.g. `[64]` or `[64, 64, 3]`.
    pub shape: Vec<usize>,
    /// Byte offset of the field inside one env's observation record.
    pub offset: usize,
    /// Lower bound of every element (`None` when unbounded; JSON has no infinity).
    pub low: Option<f64>,
    /// Upper bound of every element (`None` when unbounded).
    pub high: Option<f64>,
}

impl ObsField {
    /// Number of elements.
    pub fn len(&self) -> usize {
        self.shape.iter().product()
    }

    /// True when the field has no elements.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Size in bytes.
    pub fn byte_len(&self) -> usize {
        self.len() * self.dtype.size()
    }
}

/// The action of one env: a float32 vector with per-element bounds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ActionSpec {
    /// Number of elements.
    pub size: usize,
    /// Per-element lower bound.
    pub low: Vec<f32>,
    /// Per-element upper bound.
    pub high: Vec<f32>,
}

/// Range of a scalar such as the reward.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ScalarSpec {
    /// Lower bound (`None` when unbounded; JSON has no infinity).
    pub low: Option<f64>,
    /// Upper bound (`None` when unbounded).
    pub high: Option<f64>,
}

/// How a lease handles episodes that end during a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum AutoresetMode {
    /// Ended envs stay ended until the client resets them (torchrl's `_reset` masks);
    /// stepping one answers [`crate::StepStatus::NeedsReset`].
    #[default]
    Disabled,
    /// Ended envs are reset within the same step; the observation holds the first
    /// observation of the new episode and the final observation of the old one is in
    /// the `final_obs` block (gymnasium's `AutoresetMode.SAME_STEP`).
    SameStep,
}

/// Everything a client needs to know about an env to drive it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EnvSpec {
    /// Versioned id, e.g. `echogym/Null-v0`.
    pub env_id: String,
    /// Observation fields, in record order.
    pub observation: Vec<ObsField>,
    /// Size of one env's observation record in bytes (fields plus padding; a multiple of 8).
    pub obs_record_bytes: usize,
    /// The action.
    pub action: ActionSpec,
    /// Reward range.
    pub reward: ScalarSpec,
    /// Names of the per-step float32 info values, in order. Every spec built by
    /// [`EnvSpecBuilder`] ends with [`ENV_ERROR_KEY`].
    pub info_keys: Vec<String>,
    /// Truncation horizon (`truncated` becomes true at this many steps), if any.
    pub max_episode_steps: Option<u64>,
    /// Simulated seconds per env step (0 for envs without time).
    pub dt_s: f64,
    /// The resolved env config (defaults filled in), as JSON.
    pub config: serde_json::Value,
}

/// Info key every spec carries (the builder appends it last): 1 for an env whose step or
/// reset failed inside the server (the env's code panicked) in this exchange, else 0.
/// The other envs of the batch are unaffected. The failed env's observation and other
/// info values are 0, a failed step is truncated, and the env needs a reset (with
/// same-step autoreset the server tries one at once; the flag is then in both `info`
/// and `final_info`).
pub const ENV_ERROR_KEY: &str = "env_error";

/// Builds an [`EnvSpec`], placing observation fields at aligned offsets.
#[derive(Debug, Clone)]
#[must_use]
pub struct EnvSpecBuilder {
    spec: EnvSpec,
}

/// Alignment of every observation field inside the record.
const FIELD_ALIGN: usize = 8;

impl EnvSpec {
    /// Start a spec for `env_id` with a float32 action of `action_size` elements in `[-1, 1]`.
    pub fn builder(env_id: impl Into<String>, action_size: usize) -> EnvSpecBuilder {
        EnvSpecBuilder {
            spec: EnvSpec {
                env_id: env_id.into(),
                observation: Vec::new(),
                obs_record_bytes: 0,
                action: ActionSpec {
                    size: action_size,
                    low: vec![-1.0; action_size],
                    high: vec![1.0; action_size],
                },
                reward: ScalarSpec {
                    low: None,
                    high: None,
                },
                info_keys: Vec::new(),
                max_episode_steps: None,
                dt_s: 0.0,
                config: serde_json::Value::Null,
            },
        }
    }

    /// Look up an observation field by name.
    pub fn field(&self, name: &str) -> Option<&ObsField> {
        self.observation.iter().find(|f| f.name == name)
    }
}

impl EnvSpecBuilder {
    /// Append an observation field with the given bounds (`None`: unbounded).
    pub fn field(
        mut self,
        name: &str,
        dtype: DType,
        shape: &[usize],
        low: Option<f64>,
        high: Option<f64>,
    ) -> Self {
        let offset = self.spec.obs_record_bytes.next_multiple_of(FIELD_ALIGN);
        let field = ObsField {
            name: name.to_owned(),
            dtype,
            shape: shape.to_vec(),
            offset,
            low,
            high,
        };
        self.spec.obs_record_bytes = (offset + field.byte_len()).next_multiple_of(FIELD_ALIGN);
        self.spec.observation.push(field);
        self
    }

    /// Append an unbounded float32 observation field.
    pub fn f32_field(self, name: &str, shape: &[usize]) -> Self {
        self.field(name, DType::Float32, shape, None, None)
    }

    /// Set per-element action bounds (lengths must equal the action size).
    pub fn action_bounds(mut self, low: Vec<f32>, high: Vec<f32>) -> Self {
        debug_assert_eq!(low.len(), self.spec.action.size);
        debug_assert_eq!(high.len(), self.spec.action.size);
        self.spec.action.low = low;
        self.spec.action.high = high;
        self
    }

    /// Set the reward range.
    pub fn reward_range(mut self, low: Option<f64>, high: Option<f64>) -> Self {
        self.spec.reward = ScalarSpec { low, high };
        self
    }

    /// Declare a per-step float32 info value.
    pub fn info_key(mut self, key: &str) -> Self {
        self.spec.info_keys.push(key.to_owned());
        self
    }

    /// Set the truncation horizon.
    pub fn max_episode_steps(mut self, steps: Option<u64>) -> Self {
        self.spec.max_episode_steps = steps;
        self
    }

    /// Set the simulated seconds per env step.
    pub fn dt_s(mut self, dt_s: f64) -> Self {
        self.spec.dt_s = dt_s;
        self
    }

    /// Attach the resolved config.
    pub fn config(mut self, config: serde_json::Value) -> Self {
        self.spec.config = config;
        self
    }

    /// Finish the spec, appending [`ENV_ERROR_KEY`] to the info keys (once).
    pub fn build(mut self) -> EnvSpec {
        self.spec.info_keys.retain(|k| k != ENV_ERROR_KEY);
        self.spec.info_keys.push(ENV_ERROR_KEY.to_owned());
        self.spec
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_aligned_and_record_is_padded() {
        let spec = EnvSpec::builder("x", 2)
            .field("img", DType::Uint8, &[3, 3], Some(0.0), Some(255.0))
            .f32_field("obs", &[3])
            .build();
        assert_eq!(spec.observation[0].offset, 0);
        assert_eq!(spec.observation[1].offset, 16);
        assert_eq!(spec.obs_record_bytes, 32);
        assert_eq!(spec.field("obs").unwrap().byte_len(), 12);
    }

    #[test]
    fn spec_round_trips_through_json() {
        let spec = EnvSpec::builder("echogym/Null-v0", 7)
            .f32_field("obs", &[64])
            .info_key("step")
            .max_episode_steps(Some(10))
            .build();
        assert_eq!(spec.info_keys, ["step", ENV_ERROR_KEY]);
        let text = serde_json::to_string(&spec).unwrap();
        let back: EnvSpec = serde_json::from_str(&text).unwrap();
        assert_eq!(spec, back);
    }
}
