//! The [`Env`] trait and the output record an env writes into.

use echogym_protocol::{DType, ObsField};

/// Reward and termination of one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Transition {
    /// Reward of the step.
    pub reward: f32,
    /// The episode reached a terminal state (success or failure, not a time limit).
    pub terminated: bool,
}

/// Info key an env declares to hear of a physics error: a step whose observation or
/// reward came out non-finite (an unstable configuration blew up) is truncated by the
/// batch, its non-finite values are replaced by 0 (clients never see NaN), and this key
/// is 1 for that step. `status` counts such steps for every env, declared or not.
pub const PHYSICS_ERROR_KEY: &str = "physics_error";

/// One environment instance.
///
/// Actions handed to [`Env::step`] are already checked finite and clipped to the spec's
/// bounds; time limits are applied by the pool, not by the env.
pub trait Env: Send {
    /// Start a new episode; `seed` reseeds the env's random generator when given.
    fn reset(&mut self, seed: Option<u64>, out: &mut EnvOutput<'_>);

    /// Advance one step.
    fn step(&mut self, action: &[f32], out: &mut EnvOutput<'_>) -> Transition;

    /// Write the current observation again without changing state (for envs left
    /// alone by a partial reset).
    fn observe(&self, out: &mut EnvOutput<'_>);
}

/// The observation record and info row of one env, inside the shared-memory sample.
pub struct EnvOutput<'a> {
    fields: &'a [ObsField],
    record: &'a mut [u8],
    info: &'a mut [f32],
}

impl<'a> EnvOutput<'a> {
    /// Wrap one env's record (laid out by `fields`) and info row.
    pub fn new(fields: &'a [ObsField], record: &'a mut [u8], info: &'a mut [f32]) -> Self {
        Self {
            fields,
            record,
            info,
        }
    }

    /// The float32 field at `index` (in spec order).
    ///
    /// # Panics
    /// If the field is not float32: a bug in the env, caught by the pool.
    pub fn f32_field(&mut self, index: usize) -> &mut [f32] {
        let field = &self.fields[index];
        assert_eq!(
            field.dtype,
            DType::Float32,
            "field {} is not float32",
            field.name
        );
        let bytes = &mut self.record[field.offset..field.offset + field.byte_len()];
        bytemuck::cast_slice_mut(bytes)
    }

    /// The uint8 field at `index` (in spec order).
    ///
    /// # Panics
    /// If the field is not uint8: a bug in the env, caught by the pool.
    pub fn u8_field(&mut self, index: usize) -> &mut [u8] {
        let field = &self.fields[index];
        assert_eq!(
            field.dtype,
            DType::Uint8,
            "field {} is not uint8",
            field.name
        );
        &mut self.record[field.offset..field.offset + field.byte_len()]
    }

    /// The info row, one value per declared info key.
    pub fn info(&mut self) -> &mut [f32] {
        self.info
    }
}
