//! The recordings format `echogym-recordings/1`: what the calibration tool reads and what
//! envs record (a folder with `dataset.json` and one CSV per recording, SI units, world
//! frame, z up).
//!
//! ```text
//! dataset.json  {"format": "echogym-recordings/1", "description": "...",
//!                "nominal_surface_z": m, "torso_center_xy": [m, m],
//!                "recordings": [{"file": "center_press.csv", "site": "center",
//!                                "protocol": "press"}, ...],
//!                "torso": {...}?, "notes": "..."?}      (unknown keys are kept)
//! <file>.csv    t,px,py,pz,fx,fy,fz[,vx,vy,vz][,tx,ty,tz]
//!               t in s (increasing, constant rate 100–2000 Hz), p in m (probe tip),
//!               f in N (force the body exerts on the probe: pressing down reads fz > 0),
//!               v in m/s (derived when absent), t* in N·m
//! ```
//! Reading validates everything and names the file and row of the first problem; writing
//! goes to a temporary folder renamed into place at the end, so nothing is half-written.

mod dataset;
mod error;
mod recording;
mod writer;

pub use dataset::{Dataset, DatasetMeta, FORMAT, RecordingEntry};
pub use error::RecordingsError;
pub use recording::Recording;
pub use writer::DatasetWriter;
