//! The worker pool that steps the envs of a batch in parallel.
//!
//! Parallelism is not free (waking workers costs microseconds), so a batch is split
//! only when its envs are expensive enough: the pool keeps no state, the batch passes
//! its measured per-env cost and the pool picks the chunk size.

use rayon::prelude::*;

/// Below this estimated batch cost, stepping on the calling thread beats waking workers.
const PARALLEL_THRESHOLD_NS: f64 = 20_000.0;

/// Worker threads shared by every lease.
pub struct WorkerPool {
    pool: rayon::ThreadPool,
    threads: usize,
}

/// The pool's threads could not be started.
#[derive(Debug, thiserror::Error)]
#[error("cannot start {threads} worker threads: {source}")]
pub struct PoolStartError {
    threads: usize,
    #[source]
    source: rayon::ThreadPoolBuildError,
}

/// Set the calling thread's nice value (background work yields the cores to the
/// dispatcher and to client processes when all are busy). Raising one's nice value
/// needs no privilege; a failure is logged and ignored.
pub(crate) fn renice_this_thread(nice: i32) {
    if nice == 0 {
        return;
    }
    // SAFETY: setpriority on this thread's own id changes only its scheduling weight.
    let result = unsafe {
        libc::setpriority(
            libc::PRIO_PROCESS,
            libc::gettid() as libc::id_t,
            nice as libc::c_int,
        )
    };
    if result != 0 {
        tracing::debug!(nice, "could not change a thread's nice value");
    }
}

impl WorkerPool {
    /// Start `threads` workers (0 = one per core) at nice value `nice` (see
    /// `ServeConfig::worker_nice`).
    pub fn new(threads: usize, nice: i32) -> Result<Self, PoolStartError> {
        let threads = if threads == 0 {
            std::thread::available_parallelism().map_or(1, |n| n.get())
        } else {
            threads
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("echogym-worker-{i}"))
            .start_handler(move |_| renice_this_thread(nice))
            // Spawned exchanges catch their panics; this is the net under that net (a
            // panic reaching rayon would otherwise abort the server).
            .panic_handler(|payload| {
                tracing::error!(
                    message = %super::panic::panic_message(payload.as_ref()),
                    "a worker task panicked"
                );
            })
            .build()
            .map_err(|source| PoolStartError { threads, source })?;
        Ok(Self { pool, threads })
    }

    /// Number of worker threads.
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Run `op` inside the pool (so nested parallel iterators use its threads).
    pub fn install<R: Send>(&self, op: impl FnOnce() -> R + Send) -> R {
        self.pool.install(op)
    }

    /// Run `task` on a worker, without waiting for it (an exchange handed off by the
    /// dispatcher). Tasks queue behind the pool's current work.
    pub fn spawn(&self, task: impl FnOnce() + Send + 'static) {
        self.pool.spawn(task);
    }

    /// Run `work` on every `(item, job)` pair, in parallel when `cost_per_item_ns` makes
    /// it worthwhile. Returns how many threads it used at most (1: this one).
    pub fn for_each<A: Send, B: Send>(
        &self,
        items: &mut [A],
        jobs: &mut [B],
        cost_per_item_ns: f64,
        work: impl Fn(&mut A, &mut B) + Sync + Send,
    ) -> usize {
        let n = items.len();
        if self.threads <= 1 || n <= 1 || cost_per_item_ns * n as f64 <= PARALLEL_THRESHOLD_NS {
            items
                .iter_mut()
                .zip(jobs.iter_mut())
                .for_each(|(a, b)| work(a, b));
            return 1;
        }
        // Chunks of at least ~threshold/2 of work each, and at most one per thread.
        let per_chunk = ((PARALLEL_THRESHOLD_NS / 2.0) / cost_per_item_ns.max(1.0)).ceil() as usize;
        let min_len = per_chunk.max(n.div_ceil(self.threads)).max(1);
        self.pool.install(|| {
            items
                .par_iter_mut()
                .zip(jobs.par_iter_mut())
                .with_min_len(min_len)
                .for_each(|(a, b)| work(a, b));
        });
        n.div_ceil(min_len).min(self.threads)
    }
}
