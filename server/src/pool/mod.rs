//! Env instances of one lease, stepped as a batch on a shared worker pool.

mod batch;
mod lane;
mod panic;
mod workers;

pub use batch::{BatchBuildError, EnvBatch, ExchangeError, Exchanged, Runner};
pub use lane::{Lane, LaneTask};
pub(crate) use panic::panic_message;
pub(crate) use workers::renice_this_thread;
pub use workers::{PoolStartError, Spread, ThreadUsage, WorkerPool};
