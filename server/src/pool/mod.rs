//! Env instances of one lease, stepped as a batch on a shared worker pool.

mod batch;
mod panic;
mod workers;

pub use batch::{BatchBuildError, EnvBatch, ExchangeError, Exchanged};
pub(crate) use panic::panic_message;
pub(crate) use workers::renice_this_thread;
pub use workers::{PoolStartError, WorkerPool};
