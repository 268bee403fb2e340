//! Physics: one world per env instance. Knows nothing of transport or Python.
//!
//! [`world::World`] wraps rapier3d (table, gravity, fixed 2 ms step, snapshots);
//! [`robot`] builds arms (the built-in Panda and UR5e URDFs, or a user's) as rapier
//! multibodies with torque actuation and the dynamics controllers need; [`torso`] is the
//! soft torso of spring-damper particle joints; [`scene::Scene`] puts arm, probe,
//! force-torque sensor, torso and table together.

pub mod camera;
pub mod controller;
pub mod ft_sensor;
pub mod ik;
pub mod probe;
pub mod robot;
pub mod scene;
pub mod torso;
pub mod ultrasound;
pub(crate) mod vec3;
pub mod world;
