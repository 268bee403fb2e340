//! [`EnvBatch`]: the envs of one lease and one exchange over them.
//!
//! An exchange reads actions from the action sample and writes observations, rewards,
//! flags and info straight into the observation sample. It runs as named stages:
//! validate (nothing is touched if any input is bad) → clip actions → split the
//! observation sample into per-env jobs → step/reset in parallel → contain failed envs
//! → report.
//!
//! An env whose step or reset panics fails alone: the other envs' results are kept, and
//! the failed env's row is zeroed, flagged ([`ENV_ERROR_KEY`]), a failed step truncated,
//! and the env needs a reset (with same-step autoreset one is tried at once).

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use echogym_protocol::{
    AutoresetMode, BatchLayout, DType, ENV_ERROR_KEY, EnvSpec, LayoutError, ObsField, Op,
    ResetFlag, StepStatus,
};

use super::panic::panic_message;
use super::workers::{ThreadUsage, WorkerPool};
use crate::envs::{Env, EnvBuildError, EnvFactory, EnvOutput, PHYSICS_ERROR_KEY, Transition};

/// Why an exchange was refused. Nothing was stepped. (A failing env does not fail
/// the exchange: it is flagged in its row, see the module docs.)
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("{status:?} (env {env_index:?}, element {element_index:?})")]
pub struct ExchangeError {
    /// The status reported to the client.
    pub status: StepStatus,
    /// The env concerned, if one.
    pub env_index: Option<usize>,
    /// The action element concerned, if one.
    pub element_index: Option<usize>,
}

impl ExchangeError {
    /// `status`, about no env in particular.
    pub fn new(status: StepStatus) -> Self {
        Self {
            status,
            env_index: None,
            element_index: None,
        }
    }

    /// `status` about `env`.
    pub fn at(status: StepStatus, env: usize) -> Self {
        Self {
            status,
            env_index: Some(env),
            element_index: None,
        }
    }
}

/// One env plus its episode bookkeeping.
struct Slot {
    env: Box<dyn Env>,
    episode_steps: u64,
    needs_reset: bool,
}

/// One env's share of an exchange: its inputs and its disjoint pieces of the output.
struct Job<'a> {
    action: &'a [f32],
    reset: ResetFlag,
    seed: u64,
    record: &'a mut [u8],
    info: &'a mut [f32],
    reward: &'a mut f32,
    terminated: &'a mut u8,
    truncated: &'a mut u8,
    final_record: Option<&'a mut [u8]>,
    final_info: Option<&'a mut [f32]>,
    /// The env's step or reset panicked (see [`ENV_ERROR_KEY`]).
    env_error: bool,
    /// The step produced a non-finite observation or reward (see [`PHYSICS_ERROR_KEY`]).
    physics_error: bool,
}

/// What one exchange did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Exchanged {
    /// Env steps taken (resets excluded).
    pub steps: u64,
    /// Steps truncated for a physics error.
    pub physics_errors: u64,
    /// Envs whose step or reset failed (panicked) and were flagged.
    pub env_errors: u64,
}

/// Where an exchange runs, which decides how its cost is measured
/// ([`EnvBatch::serial_cost_ns`]).
#[derive(Clone, Copy)]
pub enum Runner<'a> {
    /// On the calling thread, timed by the wall clock (the dispatcher's cheap inline
    /// exchanges: a clock read costs 25 ns, a CPU-time read ≈ 300 ns).
    Inline,
    /// On the calling thread, timed by [`ThreadUsage`] (the medium lane).
    Serial,
    /// On the worker pool, the envs in parallel when that pays, timed by
    /// [`ThreadUsage`] on every thread.
    Pool(&'a WorkerPool),
}

/// The typed blocks of an action sample: actions, reset flags, seeds.
type ActionBlocks<'a> = (&'a [f32], &'a [u8], &'a [u64]);

/// The envs of one lease.
pub struct EnvBatch {
    spec: EnvSpec,
    layout: BatchLayout,
    mode: AutoresetMode,
    slots: Vec<Slot>,
    /// Each env's wall time the last time it stepped on the pool (the pool hands the
    /// longest out first, see [`WorkerPool::for_each`]).
    last_step_ns: Vec<u64>,
    clipped: Vec<f32>,
    step_cost_ns: f64,
    /// Measured cost of a whole exchange run on one thread, in ns, per op (steps, resets);
    /// 0 until measured. The dispatcher runs cheap exchanges itself.
    serial_cost_ns: [f64; 2],
    /// Index of [`PHYSICS_ERROR_KEY`] in the spec's info keys, if declared.
    physics_error_info: Option<usize>,
    /// Index of [`ENV_ERROR_KEY`] in the spec's info keys (every built spec has it).
    env_error_info: Option<usize>,
}

/// Why a batch was not built.
#[derive(Debug, thiserror::Error)]
pub enum BatchBuildError {
    /// The batch does not fit a sample layout.
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// An env could not be built.
    #[error("env {index} of the batch: {source}")]
    Env {
        /// Its index in the batch.
        index: usize,
        /// Why.
        source: EnvBuildError,
    },
    /// Building an env panicked (a bug, reported rather than taking the server down).
    #[error("env {index} of the batch panicked while being built: {message}")]
    Panicked {
        /// Its index in the batch.
        index: usize,
        /// The panic's message.
        message: String,
    },
    /// The build was cancelled (its client died or gave up waiting).
    #[error("cancelled after {built} of {wanted} envs")]
    Cancelled {
        /// Envs built before the cancellation was seen.
        built: usize,
        /// Envs asked for.
        wanted: usize,
    },
}

impl EnvBatch {
    /// Build `num_envs` envs of `spec` (resolved by `factory`).
    pub fn new(
        factory: &dyn EnvFactory,
        spec: EnvSpec,
        num_envs: usize,
        mode: AutoresetMode,
    ) -> Result<Self, BatchBuildError> {
        Self::build(factory, spec, num_envs, mode, &AtomicBool::new(false))
    }

    /// [`Self::new`], checking `cancel` between envs (a big batch takes seconds) and
    /// catching a panic in any env's construction.
    pub fn build(
        factory: &dyn EnvFactory,
        spec: EnvSpec,
        num_envs: usize,
        mode: AutoresetMode,
        cancel: &AtomicBool,
    ) -> Result<Self, BatchBuildError> {
        let layout = BatchLayout::new(&spec, num_envs, mode)?;
        let mut slots = Vec::with_capacity(num_envs);
        for index in 0..num_envs {
            if cancel.load(Ordering::Relaxed) {
                return Err(BatchBuildError::Cancelled {
                    built: index,
                    wanted: num_envs,
                });
            }
            let env = catch_unwind(AssertUnwindSafe(|| factory.make(&spec)))
                .map_err(|payload| BatchBuildError::Panicked {
                    index,
                    message: panic_message(payload.as_ref()),
                })?
                .map_err(|source| BatchBuildError::Env { index, source })?;
            slots.push(Slot {
                env,
                episode_steps: 0,
                needs_reset: true,
            });
        }
        let physics_error_info = spec.info_keys.iter().position(|k| k == PHYSICS_ERROR_KEY);
        let env_error_info = spec.info_keys.iter().position(|k| k == ENV_ERROR_KEY);
        Ok(Self {
            clipped: vec![0.0; num_envs * spec.action.size],
            physics_error_info,
            env_error_info,
            spec,
            layout,
            mode,
            last_step_ns: vec![0; slots.len()],
            slots,
            step_cost_ns: 0.0,
            serial_cost_ns: [0.0; 2],
        })
    }

    /// The batch layout.
    pub fn layout(&self) -> &BatchLayout {
        &self.layout
    }

    /// The env spec.
    pub fn spec(&self) -> &EnvSpec {
        &self.spec
    }

    /// Number of envs.
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// What an exchange of `op` costs on one thread, in ns (an average of the last
    /// ones), `None` before the first.
    pub fn serial_cost_ns(&self, op: Op) -> Option<f64> {
        let cost = self.serial_cost_ns[op_index(op)];
        (cost > 0.0).then_some(cost)
    }

    /// True for a batch of no envs (never built).
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Run one exchange: read `action` (the action sample payload), write `obs` (the
    /// observation sample payload, zero-filled). Returns the env steps taken and how many
    /// were truncated for a physics error or failed (flagged, the others' results kept).
    /// `runner` says where the envs step and how the exchange's cost is measured.
    pub fn exchange(
        &mut self,
        runner: Runner<'_>,
        op: Op,
        action: &[u8],
        obs: &mut [u8],
    ) -> Result<Exchanged, ExchangeError> {
        let (actions, flags, seeds) = self.validate(op, action, obs.len())?;
        self.clip(actions);
        let mut jobs = split_jobs(&self.layout, &self.clipped, flags, seeds, obs)?;
        let steps = jobs
            .iter()
            .filter(|j| op == Op::Step && j.reset == ResetFlag::Keep)
            .count() as u64;

        let started = Instant::now();
        let fields = self.spec.observation.as_slice();
        let (mode, max_steps) = (self.mode, self.spec.max_episode_steps);
        let cost = self.step_cost_ns;
        let (physics_error_info, env_error_info) = (self.physics_error_info, self.env_error_info);
        let work = |slot: &mut Slot, job: &mut Job<'_>| {
            let outcome = catch_unwind(AssertUnwindSafe(|| {
                run_job(slot, job, fields, op, mode, max_steps, physics_error_info);
            }));
            if outcome.is_err() {
                contain_failure(slot, job, fields, op, mode, env_error_info);
            }
        };
        let serial_loop = |slots: &mut [Slot], jobs: &mut [Job<'_>]| {
            slots
                .iter_mut()
                .zip(jobs.iter_mut())
                .for_each(|(slot, job)| work(slot, job));
        };
        // What the exchange costs on one thread: `None` for the wall time below.
        let measured = match runner {
            Runner::Inline => {
                serial_loop(&mut self.slots, &mut jobs);
                None
            }
            Runner::Serial => {
                let usage = ThreadUsage::now();
                serial_loop(&mut self.slots, &mut jobs);
                Some(usage.cost_ns())
            }
            Runner::Pool(pool) => Some(
                pool.for_each(
                    &mut self.slots,
                    &mut jobs,
                    &mut self.last_step_ns,
                    cost,
                    work,
                )
                .cost_ns,
            ),
        };
        let elapsed = started.elapsed();
        let physics_errors = jobs.iter().filter(|j| j.physics_error).count() as u64;
        let env_errors = jobs.iter().filter(|j| j.env_error).count() as u64;
        drop(jobs);
        // On one thread it would take about this long: the wall time of an inline
        // exchange (cheap; a preempted dispatcher only errs towards the pool), else the
        // threads' CPU time (or wall time where a thread blocked), which the machine's
        // load does not inflate (see `ThreadUsage`).
        let serial = &mut self.serial_cost_ns[op_index(op)];
        let busy = measured.unwrap_or(elapsed.as_nanos() as u64) as f64;
        *serial = if *serial == 0.0 {
            busy.max(1.0)
        } else {
            0.8 * *serial + 0.2 * busy
        };
        if steps > 0 {
            let per_env = elapsed.as_nanos() as f64 / self.slots.len() as f64;
            self.step_cost_ns = if self.step_cost_ns == 0.0 {
                per_env
            } else {
                0.9 * self.step_cost_ns + 0.1 * per_env
            };
        }
        Ok(Exchanged {
            steps,
            physics_errors,
            env_errors,
        })
    }

    /// Check every input before anything changes; return the typed action-sample blocks.
    fn validate<'a>(
        &self,
        op: Op,
        action: &'a [u8],
        obs_len: usize,
    ) -> Result<ActionBlocks<'a>, ExchangeError> {
        let layout = &self.layout;
        let (k, a) = (layout.num_envs, layout.action_size);
        if action.len() < layout.action.total || obs_len < layout.obs.total {
            return Err(ExchangeError::new(StepStatus::ShapeMismatch));
        }
        let misaligned = || ExchangeError::new(StepStatus::ShapeMismatch);
        let actions: &[f32] = bytemuck::try_cast_slice(
            &action[layout.action.actions..layout.action.actions + k * a * 4],
        )
        .map_err(|_| misaligned())?;
        let flags = &action[layout.action.reset..layout.action.reset + k];
        let seeds: &[u64] =
            bytemuck::try_cast_slice(&action[layout.action.seeds..layout.action.seeds + k * 8])
                .map_err(|_| misaligned())?;

        for (env, (&flag, slot)) in flags.iter().zip(&self.slots).enumerate() {
            let flag =
                ResetFlag::from_u8(flag).ok_or(ExchangeError::at(StepStatus::BadResetFlag, env))?;
            if op != Op::Step || flag != ResetFlag::Keep {
                continue;
            }
            if slot.needs_reset {
                return Err(ExchangeError::at(StepStatus::NeedsReset, env));
            }
            let row = &actions[env * a..(env + 1) * a];
            if let Some(element) = row.iter().position(|x| !x.is_finite()) {
                return Err(ExchangeError {
                    status: StepStatus::NonFiniteAction,
                    env_index: Some(env),
                    element_index: Some(element),
                });
            }
        }
        Ok((actions, flags, seeds))
    }

    /// Clip actions to the spec's bounds into the batch's scratch buffer.
    fn clip(&mut self, actions: &[f32]) {
        let (low, high) = (&self.spec.action.low, &self.spec.action.high);
        for (row_out, row_in) in self
            .clipped
            .chunks_mut(low.len())
            .zip(actions.chunks(low.len()))
        {
            for (i, (out, &x)) in row_out.iter_mut().zip(row_in).enumerate() {
                *out = x.clamp(low[i], high[i]);
            }
        }
    }
}

/// Index of `op` in per-op tables.
fn op_index(op: Op) -> usize {
    match op {
        Op::Step => 0,
        Op::Reset => 1,
    }
}

/// Split the observation sample into one job per env.
fn split_jobs<'a>(
    l: &BatchLayout,
    clipped: &'a [f32],
    flags: &[u8],
    seeds: &[u64],
    obs: &'a mut [u8],
) -> Result<Vec<Job<'a>>, ExchangeError> {
    let (k, r, i) = (l.num_envs, l.obs_record_bytes, l.info_len);
    let shape = || ExchangeError::new(StepStatus::ShapeMismatch);
    let cut = |buf: &'a mut [u8], at: usize| buf.split_at_mut(at);

    let (_, rest) = cut(obs, l.obs.obs);
    let (records, rest) = cut(rest, l.obs.reward - l.obs.obs);
    let (reward, rest) = cut(rest, l.obs.terminated - l.obs.reward);
    let (terminated, rest) = cut(rest, l.obs.truncated - l.obs.terminated);
    let (truncated, rest) = cut(rest, l.obs.info - l.obs.truncated);
    let info_end = l.obs.final_obs.unwrap_or(l.obs.total);
    let (info, rest) = cut(rest, info_end - l.obs.info);
    let (final_records, final_info) = match (l.obs.final_obs, l.obs.final_info) {
        (Some(fo), Some(fi)) => {
            let (records, rest) = cut(rest, fi - fo);
            let (info, _) = cut(rest, l.obs.total - fi);
            (Some(records), Some(info))
        }
        _ => (None, None),
    };

    let reward: &mut [f32] =
        bytemuck::try_cast_slice_mut(&mut reward[..k * 4]).map_err(|_| shape())?;
    let info: &mut [f32] =
        bytemuck::try_cast_slice_mut(&mut info[..k * i * 4]).map_err(|_| shape())?;
    let mut final_records = final_records.map(|b| b[..k * r].chunks_mut(r.max(1)));
    let mut final_info = match final_info {
        Some(b) => Some(
            bytemuck::try_cast_slice_mut::<u8, f32>(&mut b[..k * i * 4])
                .map_err(|_| shape())?
                .chunks_mut(i.max(1)),
        ),
        None => None,
    };

    let a = l.action_size;
    let mut records = records[..k * r].chunks_mut(r.max(1));
    let mut info_rows = info.chunks_mut(i.max(1));
    let mut jobs = Vec::with_capacity(k);
    for (env, ((reward, terminated), truncated)) in reward
        .iter_mut()
        .zip(terminated[..k].iter_mut())
        .zip(truncated[..k].iter_mut())
        .enumerate()
    {
        jobs.push(Job {
            action: &clipped[env * a..(env + 1) * a],
            reset: ResetFlag::from_u8(flags[env]).expect("validated"),
            seed: seeds[env],
            record: records.next().unwrap_or_default(),
            info: if i == 0 {
                &mut []
            } else {
                info_rows.next().unwrap_or_default()
            },
            reward,
            terminated,
            truncated,
            final_record: final_records.as_mut().and_then(|c| c.next()),
            final_info: if i == 0 {
                None
            } else {
                final_info.as_mut().and_then(|c| c.next())
            },
            env_error: false,
            physics_error: false,
        });
    }
    Ok(jobs)
}

/// Replace the non-finite values of `record`'s float fields by 0; whether any was.
fn zero_non_finite(fields: &[ObsField], record: &mut [u8]) -> bool {
    let mut repaired = false;
    for field in fields.iter().filter(|f| f.dtype == DType::Float32) {
        let bytes = &mut record[field.offset..field.offset + 4 * field.len()];
        for chunk in bytes.chunks_exact_mut(4) {
            let v = f32::from_ne_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
            if !v.is_finite() {
                chunk.copy_from_slice(&0.0f32.to_ne_bytes());
                repaired = true;
            }
        }
    }
    repaired
}

/// One env's work for one exchange.
fn run_job(
    slot: &mut Slot,
    job: &mut Job<'_>,
    fields: &[ObsField],
    op: Op,
    mode: AutoresetMode,
    max_steps: Option<u64>,
    physics_error_info: Option<usize>,
) {
    job.info.fill(0.0);
    let mut out = EnvOutput::new(fields, job.record, job.info);
    match (job.reset, op) {
        (ResetFlag::Keep, Op::Reset) => slot.env.observe(&mut out),
        (ResetFlag::Keep, Op::Step) => {
            let Transition {
                mut reward,
                terminated,
            } = slot.env.step(job.action, &mut out);
            slot.episode_steps += 1;
            let mut truncated = max_steps.is_some_and(|m| slot.episode_steps >= m);
            let repaired = zero_non_finite(fields, job.record);
            if repaired || !reward.is_finite() {
                // The env's state is no longer physics: end the episode (a time-limit
                // style truncation, not a terminal state) and say why.
                job.physics_error = true;
                truncated = true;
                if !reward.is_finite() {
                    reward = 0.0;
                }
                if let Some(k) = physics_error_info
                    && let Some(v) = job.info.get_mut(k)
                {
                    *v = 1.0;
                }
            }
            *job.reward = reward;
            *job.terminated = u8::from(terminated);
            *job.truncated = u8::from(truncated);
            if terminated || truncated {
                match mode {
                    AutoresetMode::Disabled => slot.needs_reset = true,
                    AutoresetMode::SameStep => {
                        if let Some(final_record) = job.final_record.as_deref_mut() {
                            final_record.copy_from_slice(job.record);
                        }
                        if let Some(final_info) = job.final_info.as_deref_mut() {
                            final_info.copy_from_slice(job.info);
                        }
                        job.info.fill(0.0);
                        let mut out = EnvOutput::new(fields, job.record, job.info);
                        slot.env.reset(None, &mut out);
                        slot.episode_steps = 0;
                    }
                }
            }
        }
        (flag, _) => {
            let seed = (flag == ResetFlag::ResetWithSeed).then_some(job.seed);
            slot.env.reset(seed, &mut out);
            slot.episode_steps = 0;
            slot.needs_reset = false;
        }
    }
}

/// An env's step or reset panicked: zero what it wrote, flag it ([`ENV_ERROR_KEY`]),
/// truncate a failed step and mark the env for a reset; with same-step autoreset, a
/// failed step's env is reset at once (the zeroed row and the flag go to `final_obs`/
/// `final_info`, the flag also to `info`), and stays marked if that reset panics too.
fn contain_failure(
    slot: &mut Slot,
    job: &mut Job<'_>,
    fields: &[ObsField],
    op: Op,
    mode: AutoresetMode,
    env_error_info: Option<usize>,
) {
    job.env_error = true;
    job.physics_error = false;
    slot.needs_reset = true;
    job.record.fill(0);
    job.info.fill(0.0);
    flag_env_error(job.info, env_error_info);
    *job.reward = 0.0;
    *job.terminated = 0;
    // A failed step ends the episode (truncated); a failed reset answers a reset, whose
    // flags mean nothing (torchrl refuses a reset that reports `done`), so stays 0.
    let stepping = op == Op::Step && job.reset == ResetFlag::Keep;
    *job.truncated = u8::from(stepping);
    if !(stepping && mode == AutoresetMode::SameStep) {
        return;
    }
    if let Some(final_record) = job.final_record.as_deref_mut() {
        final_record.fill(0);
    }
    if let Some(final_info) = job.final_info.as_deref_mut() {
        final_info.fill(0.0);
        flag_env_error(final_info, env_error_info);
    }
    job.info.fill(0.0);
    let reset = catch_unwind(AssertUnwindSafe(|| {
        let mut out = EnvOutput::new(fields, job.record, job.info);
        slot.env.reset(None, &mut out);
    }));
    if reset.is_ok() {
        slot.episode_steps = 0;
        slot.needs_reset = false;
    } else {
        job.record.fill(0);
        job.info.fill(0.0);
    }
    flag_env_error(job.info, env_error_info);
}

/// Set the [`ENV_ERROR_KEY`] value of an info row to 1.
fn flag_env_error(info: &mut [f32], env_error_info: Option<usize>) {
    if let Some(k) = env_error_info
        && let Some(v) = info.get_mut(k)
    {
        *v = 1.0;
    }
}
