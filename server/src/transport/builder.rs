//! Env construction and destruction off the dispatcher thread.
//!
//! Building a batch costs ≈ 1.5 ms per soft-torso env (64 envs ≈ 0.1 s, 65,536 ≈ 100 s);
//! on the dispatcher it would stall every other client's steps for that long. The
//! dispatcher hands the work to this thread and keeps serving; it answers the attach when
//! the batch comes back, or drops it if the client died or stopped waiting meanwhile (the
//! build is cancelled between envs). Detached batches are dropped here too: freeing 64
//! torsos is not free either.
//!
//! The builder also opens the new lease's services (its own iceoryx2 node, `echogym-
//! build-<name>-<pid>`, creates them): creating three services and preallocating their
//! samples took 9–36 ms for 64 scan envs on the dispatcher, a stall for every other
//! client. The dispatcher gets the ready [`Lease`] and answers the attach.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use echogym_protocol::services::ServiceError;
use echogym_protocol::{AutoresetMode, EnvSpec, ServiceNames};
use iceoryx2::prelude::Node;

use super::Ipc;
use super::lease::Lease;
use crate::envs::EnvRegistry;
use crate::pool::{BatchBuildError, EnvBatch};

/// One batch to build.
pub(super) struct BuildJob {
    /// Matches the result to the waiting attach.
    pub ticket: u64,
    /// The spec the dispatcher resolved (validated, so a build error is rare).
    pub spec: EnvSpec,
    /// Envs in the batch.
    pub num_envs: usize,
    /// Autoreset mode of the batch.
    pub mode: AutoresetMode,
    /// Set by the dispatcher when nobody waits for the batch any more.
    pub cancel: Arc<AtomicBool>,
    /// The lease to open once the batch is built.
    pub lease_id: u64,
    /// The attaching client's node.
    pub client_node: u128,
    /// The attaching client's label.
    pub client_label: String,
}

/// Why a build did not end in an open lease.
#[derive(Debug, thiserror::Error)]
pub(super) enum AttachBuildError {
    /// The envs were not built (or the build was cancelled).
    #[error(transparent)]
    Build(#[from] BatchBuildError),
    /// The lease's services could not be opened (the batch was dropped).
    #[error(transparent)]
    Open(#[from] ServiceError),
}

/// A finished (or failed, or cancelled) build.
pub(super) struct Built {
    /// The job's ticket.
    pub ticket: u64,
    /// The open lease, or why there is none.
    pub result: Result<Lease, AttachBuildError>,
    /// How long the build took.
    pub elapsed: Duration,
}

enum Work {
    Build(Box<BuildJob>),
    Discard(Box<EnvBatch>),
}

/// The builder thread and its two queues.
pub(super) struct Builder {
    work: Option<Sender<Work>>,
    done: Receiver<Built>,
    thread: Option<JoinHandle<()>>,
}

impl Builder {
    /// Start the thread; it builds from `registry` and opens leases' services named by
    /// `names` through `node` (the builder's own).
    pub fn start(
        registry: Arc<EnvRegistry>,
        node: Node<Ipc>,
        names: ServiceNames,
    ) -> std::io::Result<Self> {
        let (work, jobs) = channel::<Work>();
        let (finished, done) = channel::<Built>();
        let thread = std::thread::Builder::new()
            .name("echogym-builder".into())
            .spawn(move || {
                crate::pool::renice_this_thread(BUILDER_NICE);
                for work in jobs {
                    match work {
                        Work::Build(job) => {
                            let started = Instant::now();
                            let result = build(&registry, &job)
                                .map_err(AttachBuildError::from)
                                .and_then(|batch| open(&node, &names, &job, batch));
                            let built = Built {
                                ticket: job.ticket,
                                result,
                                elapsed: started.elapsed(),
                            };
                            if finished.send(built).is_err() {
                                return; // the dispatcher is gone
                            }
                        }
                        Work::Discard(batch) => drop_caught(*batch),
                    }
                }
            })?;
        Ok(Self {
            work: Some(work),
            done,
            thread: Some(thread),
        })
    }

    /// Queue a build; its result comes back through [`Self::finished`]. False if the
    /// builder thread is gone (it catches every panic, so only a bug gets here).
    #[must_use]
    pub fn build(&self, job: BuildJob) -> bool {
        self.send(Work::Build(Box::new(job)))
    }

    /// Drop `batch` on the builder thread (here, if the thread is gone).
    pub fn discard(&self, batch: EnvBatch) {
        let _ = self.send(Work::Discard(Box::new(batch)));
    }

    fn send(&self, work: Work) -> bool {
        let Some(sender) = &self.work else {
            return false;
        };
        match sender.send(work) {
            Ok(()) => true,
            Err(_returned) => {
                tracing::error!("the builder thread is gone");
                false
            }
        }
    }

    /// The next finished build, if any.
    pub fn finished(&self) -> Option<Built> {
        self.done.try_recv().ok()
    }
}

impl Drop for Builder {
    /// Finish queued drops, then stop (queued builds were cancelled by the dispatcher).
    fn drop(&mut self) {
        drop(self.work.take());
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// Building is background work: at nice +10 the scheduler gives the dispatcher and the
/// workers stepping other clients' envs the cores first when they are all busy.
const BUILDER_NICE: i32 = 10;

/// Open the lease of `job` over `batch`, unless the build was cancelled meanwhile.
fn open(
    node: &Node<Ipc>,
    names: &ServiceNames,
    job: &BuildJob,
    batch: EnvBatch,
) -> Result<Lease, AttachBuildError> {
    if job.cancel.load(std::sync::atomic::Ordering::Relaxed) {
        drop_caught(batch);
        return Err(BatchBuildError::Cancelled {
            built: job.num_envs,
            wanted: job.num_envs,
        }
        .into());
    }
    Lease::open(
        node,
        names,
        job.lease_id,
        batch,
        job.client_node,
        job.client_label.clone(),
    )
    .map_err(|failed| {
        let (error, batch) = *failed;
        drop_caught(batch);
        error.into()
    })
}

/// Drop `batch`, containing a panic in an env's drop.
fn drop_caught(batch: EnvBatch) {
    if catch_unwind(AssertUnwindSafe(|| drop(batch))).is_err() {
        tracing::error!("an env panicked while being dropped");
    }
}

fn build(registry: &EnvRegistry, job: &BuildJob) -> Result<EnvBatch, BatchBuildError> {
    let factory = registry
        .get(&job.spec.env_id)
        .map_err(|e| BatchBuildError::Env {
            index: 0,
            source: crate::envs::EnvBuildError::new(&job.spec.env_id, e),
        })?;
    EnvBatch::build(
        factory,
        job.spec.clone(),
        job.num_envs,
        job.mode,
        &job.cancel,
    )
}
