//! The worker pool that steps the envs of a batch in parallel.
//!
//! Parallelism is not free (waking workers costs microseconds), so a batch is split
//! only when its envs are expensive enough: the pool keeps no state, the batch passes
//! its measured per-env cost (to decide whether to split and in what grains) and each
//! env's last step time (to hand out the longest first).

use std::cmp::Reverse;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

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
    /// it worthwhile. Returns how many threads it used at most (1: this one) and what the
    /// work cost, summed over the threads ([`ThreadUsage::cost_ns`]).
    ///
    /// `last_ns[i]` is item `i`'s wall time the last time it ran in parallel; this call
    /// orders by it and overwrites it. In parallel, the items are handed out one by one
    /// (in grains of ≈ 10 µs of work when they are cheap), longest first, to whichever
    /// thread is free. A batch ends when its slowest thread does, and env steps differ by
    /// 4× (an env in contact against one in free space) while a VM's cores differ in
    /// speed: fixed equal shares left threads idle (16 threads: 6,533 env-steps/s against
    /// 9,324 longest-first, docs/benchmarks.md "Scaling"); greedy longest-first keeps the
    /// makespan within 4/3 of the optimum.
    pub fn for_each<A: Send, B: Send>(
        &self,
        items: &mut [A],
        jobs: &mut [B],
        last_ns: &mut [u64],
        cost_per_item_ns: f64,
        work: impl Fn(&mut A, &mut B) + Sync + Send,
    ) -> Spread {
        let n = items.len();
        if self.threads <= 1 || n <= 1 || cost_per_item_ns * n as f64 <= PARALLEL_THRESHOLD_NS {
            let usage = ThreadUsage::now();
            items
                .iter_mut()
                .zip(jobs.iter_mut())
                .for_each(|(a, b)| work(a, b));
            return Spread {
                threads: 1,
                cost_ns: usage.cost_ns(),
            };
        }
        let grain = ((PARALLEL_THRESHOLD_NS / 2.0) / cost_per_item_ns.max(1.0)).ceil() as usize;
        let grain = grain.clamp(1, n.div_ceil(self.threads));
        let mut queue: Vec<_> = items
            .iter_mut()
            .zip(jobs.iter_mut())
            .zip(last_ns.iter_mut())
            .collect();
        queue.sort_by_key(|(_, last)| Reverse(**last));
        let queue = Mutex::new(queue.into_iter());
        let workers = n.div_ceil(grain).min(self.threads);
        let cost_ns = AtomicU64::new(0);
        let drain = || {
            let usage = ThreadUsage::now();
            loop {
                let taken: Vec<_> = {
                    let mut queue = queue.lock().unwrap_or_else(|e| e.into_inner());
                    queue.by_ref().take(grain).collect()
                };
                if taken.is_empty() {
                    break;
                }
                for ((a, b), last) in taken {
                    let started = Instant::now();
                    work(a, b);
                    *last = started.elapsed().as_nanos() as u64;
                }
            }
            cost_ns.fetch_add(usage.cost_ns(), Ordering::Relaxed);
        };
        self.pool.install(|| {
            rayon::scope(|scope| {
                for _ in 1..workers {
                    scope.spawn(|_| drain());
                }
                drain();
            })
        });
        Spread {
            threads: workers,
            cost_ns: cost_ns.into_inner(),
        }
    }
}

/// How [`WorkerPool::for_each`] ran.
#[derive(Debug, Clone, Copy)]
pub struct Spread {
    /// Threads used at most.
    pub threads: usize,
    /// What the work cost on all of them together, in ns ([`ThreadUsage::cost_ns`]).
    pub cost_ns: u64,
}

/// A snapshot of the calling thread's resource use, to measure what a piece of work
/// costs independently of how busy the machine is.
///
/// Wall time counts the time a thread waited for a core: on 2 cores shared by a big
/// batch's workers and other processes, a 0.4 ms exchange took 2–4 ms of wall time, so
/// its wall-clock cost could not tell it from a big one. CPU time does not count that,
/// but it also misses a thread that sleeps or waits for I/O or a lock, which holds its
/// thread all the same; such a thread switches out voluntarily. So the cost is the CPU
/// time, or the wall time if the thread blocked meanwhile. Four system calls (≈ 0.3 µs
/// each) a measurement: for work of ≥ 100 µs, not for the dispatcher's inline exchanges.
#[derive(Debug, Clone, Copy)]
pub struct ThreadUsage {
    wall: Instant,
    cpu_ns: u64,
    voluntary_switches: i64,
}

impl ThreadUsage {
    /// The calling thread's use so far.
    pub fn now() -> Self {
        let (cpu_ns, voluntary_switches) = thread_rusage();
        Self {
            wall: Instant::now(),
            cpu_ns,
            voluntary_switches,
        }
    }

    /// What ran on the calling thread since `self` (taken on the same thread) cost, ns:
    /// its CPU time, or its wall time if the thread blocked meanwhile.
    pub fn cost_ns(&self) -> u64 {
        let wall = self.wall.elapsed().as_nanos() as u64;
        let (cpu_ns, voluntary_switches) = thread_rusage();
        if voluntary_switches != self.voluntary_switches {
            wall
        } else {
            // Never above the wall time (the two clocks' resolutions differ).
            cpu_ns.saturating_sub(self.cpu_ns).min(wall)
        }
    }
}

/// The calling thread's CPU time (ns, `CLOCK_THREAD_CPUTIME_ID`: exact, where
/// `getrusage`'s user and system times move in ticks) and its voluntary context switches.
fn thread_rusage() -> (u64, i64) {
    // SAFETY: both calls write only the structs we pass, about the calling thread.
    unsafe {
        let mut time: libc::timespec = std::mem::zeroed();
        let cpu_ns = if libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut time) == 0 {
            time.tv_sec as u64 * 1_000_000_000 + time.tv_nsec as u64
        } else {
            0
        };
        let mut usage: libc::rusage = std::mem::zeroed();
        let switches = if libc::getrusage(libc::RUSAGE_THREAD, &mut usage) == 0 {
            usage.ru_nvcsw as i64
        } else {
            0
        };
        (cpu_ns, switches)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fixed amount of CPU work (the same CPU time however busy the machine is).
    fn work(rounds: u64) -> u64 {
        let mut x = 1u64;
        for i in 0..rounds {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(i));
        }
        x
    }

    #[test]
    fn usage_counts_cpu_work_and_blocking() {
        let usage = ThreadUsage::now();
        let started = Instant::now();
        work(20_000_000);
        let (busy, wall) = (usage.cost_ns(), started.elapsed().as_nanos() as u64);
        assert!(busy > 0 && busy <= wall + 1_000_000, "{busy} ns of {wall}");
        // Sleeping uses no CPU but holds the thread: counted as wall time.
        let usage = ThreadUsage::now();
        std::thread::sleep(std::time::Duration::from_millis(20));
        assert!(usage.cost_ns() >= 20_000_000);
    }

    #[test]
    fn for_each_reports_the_cost_of_every_thread() {
        // One unit's CPU time on this thread, then 8 units over 2 workers.
        let usage = ThreadUsage::now();
        work(2_000_000);
        let unit = usage.cost_ns().max(1);
        let pool = WorkerPool::new(2, 0).unwrap();
        let mut items = vec![0u64; 8];
        let mut jobs = vec![(); 8];
        let mut last = vec![0u64; 8];
        let spread = pool.for_each(&mut items, &mut jobs, &mut last, 1e6, |item, _| {
            *item = work(2_000_000);
        });
        assert!(items.iter().all(|&i| i != 0));
        assert!(
            last.iter().all(|&ns| ns > 0),
            "each item's time is kept: {last:?}"
        );
        assert_eq!(spread.threads, 2);
        // The sum over both threads, not the wall time of the slower one (CPU time: the
        // same on a loaded machine; a generous band for cache and frequency effects).
        assert!(
            spread.cost_ns >= 4 * unit && spread.cost_ns <= 32 * unit,
            "{} ns for 8 units of {unit} ns",
            spread.cost_ns
        );
    }

    #[test]
    fn for_each_hands_out_the_longest_items_first() {
        // Item 5 and item 2 took longest last time: the two threads start with them.
        let pool = WorkerPool::new(2, 0).unwrap();
        let mut items: Vec<usize> = (0..8).collect();
        let mut jobs = vec![usize::MAX; 8];
        let mut last = vec![10u64, 10, 900, 10, 10, 1000, 10, 10];
        let ticket = AtomicU64::new(0);
        pool.for_each(&mut items, &mut jobs, &mut last, 1e6, |_, job| {
            *job = ticket.fetch_add(1, Ordering::SeqCst) as usize;
            work(200_000);
        });
        let mut first_two = [jobs[5], jobs[2]];
        first_two.sort();
        assert_eq!(first_two, [0, 1], "start order by item: {jobs:?}");
        // Each item's time is measured afresh.
        assert!(last.iter().all(|&ns| ns > 0 && ns != 10), "{last:?}");
    }
}
