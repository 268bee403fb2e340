//! The recordings format `echogym-recordings/1`: what the calibration tool reads and what
//! envs record (a folder with `dataset.json` and one CSV per recording, SI units, world
//! frame, z up).
//!
//! ```text
//! dataset.json  {"format": "echogym-recordings/1", "description": "...",
//!                "nominal_surface_z": m, "torso_center_xy": [m, m],
//!                "recordings": [{"file": "center_press.csv", "site": "center",
//!                                "protocol": "press", "session_time_s": s?}, ...],
//!                "torso": {...}?, "notes": "..."?}      (unknown keys are kept)
//! <file>.csv    t,px,py,pz,fx,fy,fz[,vx,vy,vz][,tx,ty,tz]
//!               t in s (strictly increasing, jitter allowed, median rate 50–2000 Hz,
//!               at least 10 samples), p in m (probe tip),
//!               f in N (force the body exerts on the probe: pressing down reads fz > 0),
//!               v in m/s (derived when absent), t* in N·m
//! ```
//! Recordings are listed in the order they were recorded. `session_time_s` (optional) is
//! the time of the file's first sample on a clock common to the session; without it the
//! recordings are taken as made back to back (see `calibrate::session`: a drifting
//! sensor bias is measured on this clock).
//!
//! Reading validates everything and names the file and row of the first problem (NaN or
//! infinite values, time not strictly increasing) or the file (median rate outside
//! 50–2000 Hz, fewer than [`MIN_SAMPLES`] samples). Real robot logs drop messages: an
//! interval longer than max([`GAP_FACTOR`] × median interval, [`GAP_MIN_S`]) = max(5 ×
//! median, 0.05 s) is a gap, and a file with gaps is read as one recording per segment
//! (listed as `<file>#1`, `<file>#2`, … with the file's site, protocol and other keys, time
//! stamps unchanged, velocities derived per segment); segments under [`MIN_SAMPLES`] are
//! dropped with a warning, and a file with none left is refused. Writing goes to a
//! temporary folder renamed into place at the end, so nothing is half-written.

mod dataset;
mod error;
mod recording;
pub mod root;
mod writer;

pub use dataset::{Dataset, DatasetMeta, FORMAT, RecordingEntry, Segment};
pub use error::RecordingsError;
pub use recording::{GAP_FACTOR, GAP_MIN_S, MIN_SAMPLES, RATE_RANGE_HZ, Recording};
pub use writer::{DatasetWriter, QUEUED_RECORDINGS};
