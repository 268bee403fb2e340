//! The arena shared by the physics envs: config, observations and cameras, domain
//! randomization, episode recording, and the generic env that runs a [`Task`].

mod arena_env;
mod config;
mod observation;
mod part;
mod randomization;
mod recorder;
mod scene_state;
mod shaded_render;

use rapier3d::prelude::Rotation;

pub use arena_env::{ArenaEnv, ArenaFactory, Task};
pub use config::{ArenaConfig, RecordConfig, TaskConfig};
pub use observation::{CAMERA_FAR, CAMERA_PRESETS, CameraConfig, Observation, Shading};
pub use part::Part;
pub use randomization::{Draw, Randomization, gaussian};
pub use recorder::EpisodeRecorder;
pub use scene_state::{
    COLLIDER_COLUMNS, CONTACT_LEN, SCENE_FIELDS, SceneStateSize, ShapeKind, VERTEX_COLUMNS,
};
pub use shaded_render::render_shaded;

/// The probe upright: face down (probe z along world −z), array along world y.
pub fn upright() -> Rotation {
    Rotation::from_rotation_x(std::f32::consts::PI as _)
}
#[cfg(test)]
mod tests;
