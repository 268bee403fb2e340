//! Env instances of one lease, stepped as a batch on a shared worker pool.

mod batch;
mod workers;

pub use batch::{BatchBuildError, EnvBatch, ExchangeError, Exchanged};
pub use workers::{PoolStartError, WorkerPool};
