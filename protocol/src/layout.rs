//! Where each part of a batch lives inside the action and observation samples.
//!
//! Both samples are plain byte slices whose start is aligned to [`PAYLOAD_ALIGN`]. Each
//! block starts at a multiple of [`PAYLOAD_ALIGN`] so that blocks never share a cache
//! line and every element is naturally aligned (numpy views need no copies).
//!
//! Action sample (client → server), for `K` envs with action size `A`:
//! ```text
//! actions   f32[K][A]
//! reset     u8[K]      ResetFlag per env
//! seeds     u64[K]     read where reset == ResetWithSeed
//! ```
//! Observation sample (server → client), with an observation record of `R` bytes and
//! `I` info keys:
//! ```text
//! obs         u8[K][R]   fields at ObsField::offset inside each record
//! reward      f32[K]
//! terminated  u8[K]
//! truncated   u8[K]
//! info        f32[K][I]
//! final_obs   u8[K][R]   only with AutoresetMode::SameStep
//! final_info  f32[K][I]  only with AutoresetMode::SameStep
//! ```

use serde::{Deserialize, Serialize};

use crate::spec::{AutoresetMode, DType, EnvSpec};

/// Alignment of sample payloads and of every block inside them, in bytes.
pub const PAYLOAD_ALIGN: usize = 64;

/// Largest batch a single lease may hold.
const MAX_ENVS_PER_LEASE: usize = 1 << 16;

/// Largest sample payload, in bytes (1 GiB); anything larger is surely a config mistake.
const MAX_PAYLOAD_BYTES: usize = 1 << 30;

/// Why a layout cannot be built.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum LayoutError {
    /// The batch has no envs or more than the limit.
    #[error("num_envs must be between 1 and {max}, got {got}")]
    BadNumEnvs {
        /// The requested number.
        got: usize,
        /// The limit.
        max: usize,
    },
    /// The payload would exceed the size limit.
    #[error(
        "a batch of {num_envs} envs needs {bytes} bytes per sample, more than the limit of {max}"
    )]
    TooLarge {
        /// The requested number of envs.
        num_envs: usize,
        /// The bytes needed.
        bytes: usize,
        /// The limit.
        max: usize,
    },
}

/// Block offsets of the action sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ActionLayout {
    /// Byte offset of `f32[K][A]` actions.
    pub actions: usize,
    /// Byte offset of the `u8[K]` reset mask.
    pub reset: usize,
    /// Byte offset of the `u64[K]` seeds.
    pub seeds: usize,
    /// Total payload bytes.
    pub total: usize,
}

/// Block offsets of the observation sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ObsLayout {
    /// Byte offset of the `u8[K][R]` observation records.
    pub obs: usize,
    /// Byte offset of `f32[K]` rewards.
    pub reward: usize,
    /// Byte offset of `u8[K]` terminated flags.
    pub terminated: usize,
    /// Byte offset of `u8[K]` truncated flags.
    pub truncated: usize,
    /// Byte offset of `f32[K][I]` info values.
    pub info: usize,
    /// Byte offset of the final observations (same-step autoreset only).
    pub final_obs: Option<usize>,
    /// Byte offset of the final info values (same-step autoreset only).
    pub final_info: Option<usize>,
    /// Total payload bytes.
    pub total: usize,
}

/// The full layout of one lease's batch.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct BatchLayout {
    /// Envs in the batch (`K`).
    pub num_envs: usize,
    /// Action elements per env (`A`).
    pub action_size: usize,
    /// Bytes of one observation record (`R`).
    pub obs_record_bytes: usize,
    /// Info values per env (`I`).
    pub info_len: usize,
    /// The action sample.
    pub action: ActionLayout,
    /// The observation sample.
    pub obs: ObsLayout,
}

impl BatchLayout {
    /// Bytes of shared memory the lease's two channels preallocate (payloads; headers
    /// and alignment add a little).
    pub fn shared_memory_bytes(&self) -> usize {
        crate::services::LEASE_CHANNEL_SAMPLES
            .saturating_mul(self.action.total.saturating_add(self.obs.total))
    }
}

/// A strided view of one observation field across the batch, for building array views.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldView {
    /// Byte offset of env 0's field inside the sample payload.
    pub offset: usize,
    /// Element type.
    pub dtype: DType,
    /// Shape `[K, ...field shape]`.
    pub shape: Vec<usize>,
    /// Byte strides matching `shape`.
    pub strides: Vec<usize>,
}

/// Byte strides of a C-contiguous array of `shape` with `elem`-byte elements.
pub fn contiguous_strides(shape: &[usize], elem: usize) -> Vec<usize> {
    let mut strides = vec![0; shape.len()];
    let mut stride = elem;
    for d in (0..shape.len()).rev() {
        strides[d] = stride;
        stride *= shape[d];
    }
    strides
}

fn align(offset: usize) -> usize {
    offset.next_multiple_of(PAYLOAD_ALIGN)
}

impl BatchLayout {
    /// Lay out a batch of `num_envs` envs of `spec` under `mode`.
    pub fn new(spec: &EnvSpec, num_envs: usize, mode: AutoresetMode) -> Result<Self, LayoutError> {
        if num_envs == 0 || num_envs > MAX_ENVS_PER_LEASE {
            return Err(LayoutError::BadNumEnvs {
                got: num_envs,
                max: MAX_ENVS_PER_LEASE,
            });
        }
        let k = num_envs;
        let a = spec.action.size;
        let r = spec.obs_record_bytes;
        let i = spec.info_keys.len();

        let actions = 0;
        let reset = align(actions + k * a * 4);
        let seeds = align(reset + k);
        let action = ActionLayout {
            actions,
            reset,
            seeds,
            total: align(seeds + k * 8),
        };

        let obs = 0;
        let reward = align(obs + k * r);
        let terminated = align(reward + k * 4);
        let truncated = align(terminated + k);
        let info = align(truncated + k);
        let mut end = align(info + k * i * 4);
        let (final_obs, final_info) = match mode {
            AutoresetMode::Disabled => (None, None),
            AutoresetMode::SameStep => {
                let final_obs = end;
                let final_info = align(final_obs + k * r);
                end = align(final_info + k * i * 4);
                (Some(final_obs), Some(final_info))
            }
        };
        let obs = ObsLayout {
            obs,
            reward,
            terminated,
            truncated,
            info,
            final_obs,
            final_info,
            total: end,
        };
        let bytes = action.total.max(obs.total);
        if bytes > MAX_PAYLOAD_BYTES {
            return Err(LayoutError::TooLarge {
                num_envs,
                bytes,
                max: MAX_PAYLOAD_BYTES,
            });
        }
        Ok(Self {
            num_envs,
            action_size: a,
            obs_record_bytes: r,
            info_len: i,
            action,
            obs,
        })
    }

    /// The strided view of `field` across the batch, starting at the block `block_offset`
    /// (the `obs` block, or the `final_obs` block).
    pub fn field_view(&self, block_offset: usize, field: &crate::ObsField) -> FieldView {
        let elem = field.dtype.size();
        let mut shape = Vec::with_capacity(field.shape.len() + 1);
        shape.push(self.num_envs);
        shape.extend_from_slice(&field.shape);
        let mut strides = contiguous_strides(&shape, elem);
        strides[0] = self.obs_record_bytes;
        FieldView {
            offset: block_offset + field.offset,
            dtype: field.dtype,
            shape,
            strides,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn null_spec() -> EnvSpec {
        EnvSpec::builder("echogym/Null-v0", 7)
            .f32_field("obs", &[64])
            .info_key("step")
            .build()
    }

    /// Golden offsets: the Python side trusts these through the attach reply, but older
    /// clients of the same protocol version must see the same numbers.
    #[test]
    fn golden_null_layout() {
        let layout = BatchLayout::new(&null_spec(), 3, AutoresetMode::SameStep).unwrap();
        assert_eq!(
            layout.action,
            ActionLayout {
                actions: 0,
                reset: 128,
                seeds: 192,
                total: 256
            }
        );
        assert_eq!(
            layout.obs,
            ObsLayout {
                obs: 0,
                reward: 768,
                terminated: 832,
                truncated: 896,
                info: 960,
                final_obs: Some(1024),
                final_info: Some(1792),
                total: 1856,
            }
        );
        let disabled = BatchLayout::new(&null_spec(), 3, AutoresetMode::Disabled).unwrap();
        assert_eq!(disabled.obs.final_obs, None);
        assert_eq!(disabled.obs.total, 1024);
    }

    #[test]
    fn field_view_strides_follow_the_record() {
        let spec = EnvSpec::builder("x", 1)
            .f32_field("a", &[2])
            .field("img", DType::Uint8, &[4, 5, 3], None, None)
            .build();
        let layout = BatchLayout::new(&spec, 2, AutoresetMode::Disabled).unwrap();
        let view = layout.field_view(layout.obs.obs, spec.field("img").unwrap());
        assert_eq!(view.offset, 8);
        assert_eq!(view.shape, vec![2, 4, 5, 3]);
        assert_eq!(view.strides, vec![spec.obs_record_bytes, 15, 3, 1]);
    }

    #[test]
    fn rejects_empty_and_huge_batches() {
        assert!(matches!(
            BatchLayout::new(&null_spec(), 0, AutoresetMode::Disabled),
            Err(LayoutError::BadNumEnvs { .. })
        ));
        let big = EnvSpec::builder("x", 1).f32_field("a", &[1 << 20]).build();
        assert!(matches!(
            BatchLayout::new(&big, 1 << 10, AutoresetMode::Disabled),
            Err(LayoutError::TooLarge { .. })
        ));
    }
}
