//! Spin-then-block waiting on the client side (mirror of the dispatcher's protocol).

use std::time::{Duration, Instant};

use echogym_protocol::pacing::pause;

use iceoryx2::port::listener::Listener;
use iceoryx2::prelude::*;

/// How long one blocking wait lasts before liveness is checked again.
pub(crate) const LIVENESS_TICK: Duration = Duration::from_millis(50);

/// Poll `try_take` for `spin`, then alternate draining `listener`, one more poll, and a
/// blocking wait of [`LIVENESS_TICK`], calling `check_alive` after each blocking wait.
pub(crate) fn spin_then_block<T, E>(
    spin: Duration,
    listener: &Listener<ipc_threadsafe::Service>,
    mut try_take: impl FnMut() -> Result<Option<T>, E>,
    mut check_alive: impl FnMut() -> Result<(), E>,
) -> Result<T, E> {
    let started = Instant::now();
    loop {
        if let Some(value) = try_take()? {
            return Ok(value);
        }
        let waited = started.elapsed();
        if waited >= spin {
            break;
        }
        pause(waited);
    }
    loop {
        let _ = listener.try_wait(|_| {});
        if let Some(value) = try_take()? {
            return Ok(value);
        }
        let _ = listener.timed_wait(|_| {}, LIVENESS_TICK);
        if let Some(value) = try_take()? {
            return Ok(value);
        }
        check_alive()?;
    }
}
