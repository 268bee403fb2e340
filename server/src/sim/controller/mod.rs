//! Controllers turning actions into joint torques (robosuite's set and the seed thesis's
//! hybrid force/motion controller).

mod osc;

pub use osc::{Osc, OscParams};
