//! Physics: one world per env instance. Knows nothing of transport or Python.

pub mod robot;
pub mod torso;
