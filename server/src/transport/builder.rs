//! Env construction and destruction off the dispatcher thread.
//!
//! Building a batch costs ≈ 1.5 ms per soft-torso env (64 envs ≈ 0.1 s, 65,536 ≈ 100 s);
//! on the dispatcher it would stall every other client's steps for that long. The
//! dispatcher hands the work to this thread and keeps serving; it answers the attach when
//! the batch comes back, or drops it if the client died or stopped waiting meanwhile (the
//! build is cancelled between envs). Detached batches are dropped here too: freeing 64
//! torsos is not free either.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use echogym_protocol::{AutoresetMode, EnvSpec};

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
}

/// A finished (or failed, or cancelled) build.
pub(super) struct Built {
    /// The job's ticket.
    pub ticket: u64,
    /// The batch, or why there is none.
    pub result: Result<EnvBatch, BatchBuildError>,
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
    /// Start the thread; it builds from `registry`.
    pub fn start(registry: Arc<EnvRegistry>) -> std::io::Result<Self> {
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
                            let result = build(&registry, &job);
                            let built = Built {
                                ticket: job.ticket,
                                result,
                                elapsed: started.elapsed(),
                            };
                            if finished.send(built).is_err() {
                                return; // the dispatcher is gone
                            }
                        }
                        Work::Discard(batch) => {
                            if catch_unwind(AssertUnwindSafe(|| drop(batch))).is_err() {
                                tracing::error!("an env panicked while being dropped");
                            }
                        }
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
