//! [`AsyncBatch`]: envpool-style asynchronous stepping, `send(actions, env_ids)` and
//! `recv(min_envs)` returning the first envs whose observations are ready.
//!
//! The unit of asynchrony is a lease: `num_envs` envs are leased as groups of
//! `group_size`, each group its own lease with its own exchange in flight. Nothing new
//! travels on the wire: a partial batch is the group's ordinary exchange, and env ids are
//! the client's numbering (`group * group_size + slot`), never sent to the server. What
//! makes it asynchronous is that a group's observations are taken as soon as they are
//! published, while other groups are still stepping or not yet sent.

use std::collections::VecDeque;
use std::time::Instant;

use echogym_protocol::{BatchLayout, EnvSpec};
use iceoryx2::prelude::*;

use super::connection::Connection;
use super::error::{ControlCallError, LeaseError};
use super::lease::{AttachOptions, Lease};
use super::wait::LIVENESS_TICK;
use echogym_protocol::pacing::pause;

/// `num_envs` envs as groups of `group_size`, one lease per group, stepped
/// asynchronously. See the module docs.
pub struct AsyncBatch {
    leases: Vec<Lease>,
    group_size: usize,
    /// When each group's exchange in flight was sent (`None`: not in flight).
    sent_at: Vec<Option<Instant>>,
    /// Groups whose observations arrived and were not yet handed out by `recv`.
    ready: VecDeque<usize>,
    /// Scratch rows of one group's actions, in slot order.
    scratch: Vec<f32>,
}

impl Connection {
    /// Lease `options.num_envs` envs as groups of `group_size` for asynchronous stepping.
    /// `group_size` must divide `num_envs`. On failure the groups already leased are
    /// given back.
    pub fn attach_async(
        &self,
        options: &AttachOptions,
        group_size: usize,
    ) -> Result<AsyncBatch, ControlCallError> {
        if group_size == 0 || options.num_envs == 0 || !options.num_envs.is_multiple_of(group_size)
        {
            return Err(ControlCallError::Malformed(format!(
                "group_size {group_size} must be positive and divide num_envs {}",
                options.num_envs
            )));
        }
        let groups = options.num_envs / group_size;
        let group_options = AttachOptions {
            num_envs: group_size,
            ..options.clone()
        };
        // Dropping the leases attached so far (on `?`) detaches them.
        let leases = (0..groups)
            .map(|_| self.attach(&group_options))
            .collect::<Result<Vec<_>, _>>()?;
        let action_size = leases[0].layout().action_size;
        Ok(AsyncBatch {
            sent_at: vec![None; groups],
            ready: VecDeque::with_capacity(groups),
            scratch: vec![0.0; group_size * action_size],
            leases,
            group_size,
        })
    }
}

impl AsyncBatch {
    /// All envs.
    pub fn num_envs(&self) -> usize {
        self.leases.len() * self.group_size
    }

    /// Envs per group (per lease).
    pub fn group_size(&self) -> usize {
        self.group_size
    }

    /// Groups (leases).
    pub fn num_groups(&self) -> usize {
        self.leases.len()
    }

    /// The env spec (the same for every group).
    pub fn spec(&self) -> &EnvSpec {
        self.leases[0].spec()
    }

    /// One group's sample layout (`num_envs` = `group_size`).
    pub fn layout(&self) -> &BatchLayout {
        self.leases[0].layout()
    }

    /// The lease of `group`, whose current observation is that group's last received one.
    pub fn lease(&self, group: usize) -> &Lease {
        &self.leases[group]
    }

    /// The lease of `group`, mutably (e.g. to step it synchronously).
    pub fn lease_mut(&mut self, group: usize) -> &mut Lease {
        &mut self.leases[group]
    }

    /// The env ids of `group`.
    pub fn env_ids(&self, group: usize) -> std::ops::Range<usize> {
        group * self.group_size..(group + 1) * self.group_size
    }

    /// Envs sent and not yet handed out by [`AsyncBatch::recv`].
    pub fn pending_envs(&self) -> usize {
        (self.sent_at.iter().filter(|s| s.is_some()).count() + self.ready.len()) * self.group_size
    }

    /// The groups `env_ids` covers, each exactly once and whole, with for every group the
    /// position in `env_ids` of each of its slots; refused (naming the env) otherwise, or
    /// if a group is still pending.
    fn groups_of(&self, env_ids: &[usize]) -> Result<Vec<(usize, Vec<usize>)>, LeaseError> {
        let n = self.num_envs();
        let mut position = vec![usize::MAX; n];
        for (i, &id) in env_ids.iter().enumerate() {
            if id >= n {
                return Err(LeaseError::Async(format!(
                    "env id {id} out of range (0..{n})"
                )));
            }
            if position[id] != usize::MAX {
                return Err(LeaseError::Async(format!("env id {id} given twice")));
            }
            position[id] = i;
        }
        let mut groups: Vec<(usize, Vec<usize>)> = Vec::new();
        for &id in env_ids {
            let group = id / self.group_size;
            if groups.iter().any(|(g, _)| *g == group) {
                continue;
            }
            let slots: Vec<usize> = self.env_ids(group).map(|e| position[e]).collect();
            if let Some(missing) = self.env_ids(group).find(|&e| position[e] == usize::MAX) {
                return Err(LeaseError::Async(format!(
                    "env ids must cover whole groups of {}: env {id} is sent without env \
                     {missing} of its group {group} (send the ids `recv` returned)",
                    self.group_size
                )));
            }
            if self.sent_at[group].is_some() || self.ready.contains(&group) {
                return Err(LeaseError::Async(format!(
                    "env {id} was sent and its observation not yet received"
                )));
            }
            groups.push((group, slots));
        }
        Ok(groups)
    }

    /// Step the envs `env_ids` with `actions` (`env_ids.len() × action_size`, row `i` for
    /// env `env_ids[i]`) and return at once. `env_ids` must be whole groups not pending
    /// (the ids a [`AsyncBatch::recv`] returned, in any order). Nothing is sent if any
    /// check fails.
    pub fn send_step(&mut self, actions: &[f32], env_ids: &[usize]) -> Result<(), LeaseError> {
        let action_size = self.layout().action_size;
        if actions.len() != env_ids.len() * action_size {
            return Err(LeaseError::ActionShape {
                got: actions.len(),
                expected: env_ids.len() * action_size,
                num_envs: env_ids.len(),
                action_size,
            });
        }
        let groups = self.groups_of(env_ids)?;
        for (group, rows) in groups {
            for (slot, &row) in rows.iter().enumerate() {
                self.scratch[slot * action_size..(slot + 1) * action_size]
                    .copy_from_slice(&actions[row * action_size..(row + 1) * action_size]);
            }
            let base = group * self.group_size;
            self.leases[group]
                .send_step(&self.scratch, None)
                .map_err(|e| with_env_offset(e, base))?;
            self.sent_at[group] = Some(Instant::now());
        }
        Ok(())
    }

    /// Reset the envs `env_ids` (whole groups, as for [`AsyncBatch::send_step`]), each
    /// with its seed in `seeds` (one per id; `None` = keep the stream), and return at once.
    pub fn send_reset(
        &mut self,
        env_ids: &[usize],
        seeds: Option<&[Option<u64>]>,
    ) -> Result<(), LeaseError> {
        if seeds.is_some_and(|s| s.len() != env_ids.len()) {
            return Err(LeaseError::BadReset(format!(
                "seeds need one entry per env id ({})",
                env_ids.len()
            )));
        }
        let groups = self.groups_of(env_ids)?;
        for (group, rows) in groups {
            let group_seeds: Option<Vec<Option<u64>>> =
                seeds.map(|s| rows.iter().map(|&row| s[row]).collect());
            self.leases[group].send_reset(None, group_seeds.as_deref())?;
            self.sent_at[group] = Some(Instant::now());
        }
        Ok(())
    }

    /// Wait until at least `min_envs` envs' observations are in (all pending envs when
    /// fewer are pending) and return their groups, first arrived first. Groups that
    /// arrive beyond `min_envs` stay queued for the next call. Each group's observations
    /// are its lease's current sample ([`Lease::current`]) until that group is sent again.
    ///
    /// A group whose exchange was refused (e.g. `NeedsReset`) is reported as the error,
    /// with the env index in the batch's numbering; it is no longer pending, and groups
    /// that arrived before it stay queued.
    pub fn recv(&mut self, min_envs: usize) -> Result<Vec<usize>, LeaseError> {
        let wanted = min_envs.min(self.pending_envs()).div_ceil(self.group_size);
        if wanted == 0 {
            return Err(LeaseError::Async("nothing was sent to receive".into()));
        }
        let started = Instant::now();
        let spin = self.leases[0].spin();
        while self.ready.len() < wanted {
            if self.poll()? {
                continue;
            }
            let waited = started.elapsed();
            if waited < spin {
                pause(waited);
            } else {
                self.block()?;
            }
        }
        Ok(self.ready.drain(..wanted).collect())
    }

    /// Take every arrived observation; true if any arrived.
    fn poll(&mut self) -> Result<bool, LeaseError> {
        let mut any = false;
        for group in 0..self.leases.len() {
            if self.sent_at[group].is_none() {
                continue;
            }
            let base = group * self.group_size;
            match self.leases[group].try_recv() {
                Ok(Some(_)) => {
                    self.sent_at[group] = None;
                    self.ready.push_back(group);
                    any = true;
                }
                Ok(None) => {}
                Err(e) => {
                    self.sent_at[group] = None;
                    return Err(with_env_offset(e, base));
                }
            }
        }
        Ok(any)
    }

    /// Block until a pending group's server notifies (or one liveness tick passes), then
    /// check every pending group's server and deadline. The listeners are drained before
    /// the last poll, so a notification sent after it wakes the wait (the same order as
    /// the single-lease wait).
    fn block(&mut self) -> Result<(), LeaseError> {
        for (lease, sent) in self.leases.iter().zip(&self.sent_at) {
            if sent.is_some() {
                let _ = lease.listener().try_wait(|_| {});
            }
        }
        if self.poll()? {
            return Ok(());
        }
        {
            let waitset = WaitSetBuilder::new()
                .signal_handling_mode(SignalHandlingMode::Disabled)
                .create::<ipc_threadsafe::Service>()
                .map_err(|e| LeaseError::Ipc(format!("{e:?}")))?;
            let mut guards = Vec::new();
            for (lease, sent) in self.leases.iter().zip(&self.sent_at) {
                if sent.is_some() {
                    guards.push(
                        waitset
                            .attach_notification(lease.listener())
                            .map_err(|e| LeaseError::Ipc(format!("{e:?}")))?,
                    );
                }
            }
            waitset
                .wait_and_process_once_with_timeout(|_| CallbackProgression::Stop, LIVENESS_TICK)
                .map_err(|e| LeaseError::Ipc(format!("{e:?}")))?;
        }
        if self.poll()? {
            return Ok(());
        }
        for group in 0..self.leases.len() {
            if let Some(sent) = self.sent_at[group] {
                self.leases[group].check_alive(sent)?;
            }
        }
        Ok(())
    }

    /// Give every lease back.
    pub fn close(&mut self) {
        for lease in &mut self.leases {
            lease.close();
        }
    }
}

impl std::fmt::Debug for AsyncBatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AsyncBatch")
            .field("num_envs", &self.num_envs())
            .field("group_size", &self.group_size)
            .field("leases", &self.leases)
            .finish()
    }
}

/// `e` with its env index moved from the group's numbering to the batch's.
fn with_env_offset(e: LeaseError, base: usize) -> LeaseError {
    match e {
        LeaseError::NonFiniteAction { env, element } => LeaseError::NonFiniteAction {
            env: env + base,
            element,
        },
        LeaseError::NeedsReset { env } => LeaseError::NeedsReset { env: env + base },
        LeaseError::EnvFailure { env } => LeaseError::EnvFailure { env: env + base },
        other => other,
    }
}
