//! Observation fields of the physics envs (selected by config, declared in the spec) and
//! their cameras.

use echogym_protocol::{DType, EnvSpecBuilder};
use rapier3d::prelude::*;
use serde::{Deserialize, Serialize};

use super::shaded_render::render_shaded;
use crate::envs::config::EnvConfigError;
use crate::envs::env::EnvOutput;
use crate::sim::camera::Camera;
use crate::sim::scene::Scene;
use crate::sim::world::arr3;

/// A selectable observation field (float32). Frames: world unless stated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Observation {
    /// Joint positions \[rad\], `[dof]`.
    JointPos,
    /// Joint velocities [rad/s], `[dof]`.
    JointVel,
    /// Probe tip position \[m\] and orientation quaternion `(x, y, z, w)`, `[7]`.
    ProbePose,
    /// Probe tip linear [m/s] and angular [rad/s] velocity, `[6]`.
    ProbeVel,
    /// Force-torque sensor reading `[fx, fy, fz, tx, ty, tz]` in the sensor frame (z out
    /// of the face: pressing reads fz < 0) [N, N·m], `[6]`.
    Ft,
    /// 1 when the probe touched anything in the last physics step, else 0, `[1]`.
    Contact,
    /// Torso particle positions \[m\] and velocities [m/s], `[particles, 6]`.
    TorsoParticles,
    /// The task's errors (see each env's docs), `[task-specific]`.
    TaskErrors,
}

impl Observation {
    /// The field name in the spec.
    pub fn name(self) -> &'static str {
        match self {
            Self::JointPos => "joint_pos",
            Self::JointVel => "joint_vel",
            Self::ProbePose => "probe_pose",
            Self::ProbeVel => "probe_vel",
            Self::Ft => "ft",
            Self::Contact => "contact",
            Self::TorsoParticles => "torso_particles",
            Self::TaskErrors => "task_errors",
        }
    }
}

/// A camera: one of the seed's views (`front`, `side`, `bird`), the whole scene
/// (`overview`), the probe-mounted view (`probe`), or any name with an explicit `eye` and
/// `target`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraConfig {
    /// Name; fields are `<name>_rgb` (uint8 `[h, w, 3]`) and `<name>_depth` (float32
    /// `[h, w]`, metres along the optical axis).
    pub name: String,
    /// Width \[px\]. Default 64.
    #[serde(default = "default_size")]
    pub width: usize,
    /// Height \[px\]. Default 64.
    #[serde(default = "default_size")]
    pub height: usize,
    /// Deliver RGB. Default true.
    #[serde(default = "yes")]
    pub rgb: bool,
    /// Deliver depth. Default true.
    #[serde(default = "yes")]
    pub depth: bool,
    /// Vertical field of view \[deg\]. Default 45 (robosuite's).
    #[serde(default = "default_fovy")]
    pub fovy: f64,
    /// Camera position [m, world] (custom cameras; presets place themselves).
    #[serde(default)]
    pub eye: Option<[f64; 3]>,
    /// Point looked at [m, world] (custom cameras).
    #[serde(default)]
    pub target: Option<[f64; 3]>,
    /// Place the camera like this preset view (`front`, `side`, `bird`, `probe`) under
    /// any name, e.g. a viewing camera beside an observation camera of the same view.
    #[serde(default)]
    pub preset: Option<String>,
    /// `flat` (default: the cheap observation shading) or `smooth` (viewing: key light
    /// with shadows, smooth skin, part colours; ≈ 2 rays a pixel).
    #[serde(default)]
    pub shading: Shading,
    /// Render every `every`-th step since the reset and repeat the frame between
    /// (a 25 frames/s video of a 500 Hz env: 20). Default 1.
    #[serde(default = "default_every")]
    pub every: u64,
}

fn default_every() -> u64 {
    1
}

/// How a camera shades its RGB image.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shading {
    /// Each collider's flat colour under a headlight (the observation default).
    #[default]
    Flat,
    /// Shaded for viewing ([`crate::envs::arena::render_shaded`]).
    Smooth,
}

fn default_size() -> usize {
    64
}
fn yes() -> bool {
    true
}
fn default_fovy() -> f64 {
    45.0
}

/// Depth reported where a camera ray hits nothing \[m\].
pub const CAMERA_FAR: f64 = 10.0;

/// The preset views.
pub const CAMERA_PRESETS: [&str; 5] = ["front", "side", "bird", "probe", "overview"];

impl CameraConfig {
    /// Check sizes and that the camera is placeable.
    pub fn validate(&self, env_id: &str) -> Result<(), EnvConfigError> {
        let err = |message: String| EnvConfigError::Invalid {
            env_id: env_id.to_owned(),
            key: "cameras",
            message,
        };
        if !(1..=1024).contains(&self.width) || !(1..=1024).contains(&self.height) {
            return Err(err(format!(
                "camera {:?}: width and height must be in [1, 1024]",
                self.name
            )));
        }
        if !(self.rgb || self.depth) {
            return Err(err(format!(
                "camera {:?}: enable rgb, depth or both",
                self.name
            )));
        }
        if !(1..=1_000_000).contains(&self.every) {
            return Err(err(format!(
                "camera {:?}: every must be in [1, 1000000] steps",
                self.name
            )));
        }
        if !(1.0..=170.0).contains(&self.fovy) {
            return Err(err(format!(
                "camera {:?}: fovy must be in [1, 170] deg",
                self.name
            )));
        }
        let custom = self.eye.is_some() && self.target.is_some();
        if let Some(preset) = &self.preset {
            if custom || !CAMERA_PRESETS.contains(&preset.as_str()) {
                return Err(err(format!(
                    "camera {:?}: preset {preset:?} must be one of {} (and without `eye`/`target`)",
                    self.name,
                    CAMERA_PRESETS.join(", ")
                )));
            }
        } else if !custom && !CAMERA_PRESETS.contains(&self.name.as_str()) {
            return Err(err(format!(
                "camera {:?} is not a preset ({}) and has no `eye` and `target`",
                self.name,
                CAMERA_PRESETS.join(", ")
            )));
        }
        Ok(())
    }

    /// The preset view this camera takes (its `preset`, else its name).
    pub fn view(&self) -> &str {
        self.preset.as_deref().unwrap_or(&self.name)
    }

    /// Whether the camera rides on the probe (and must not see the probe itself).
    pub fn on_probe(&self) -> bool {
        self.eye.is_none() && self.view() == "probe"
    }

    /// The camera for the scene's current state (`focus`: the torso's or table's centre
    /// at the height of the work surface).
    pub fn camera(&self, scene: &Scene, focus: [f64; 3]) -> Camera {
        let (w, h) = (self.width, self.height);
        let [cx, cy, cz] = focus;
        if let (Some(eye), Some(target)) = (self.eye, self.target) {
            return Camera::look_at(eye, target, [0.0, 0.0, 1.0], self.fovy, w, h);
        }
        match self.view() {
            // Facing the robot across the torso.
            "front" => Camera::look_at(
                [cx + 0.9, cy, cz + 0.45],
                [cx - 0.15, cy, cz],
                [0.0, 0.0, 1.0],
                self.fovy,
                w,
                h,
            ),
            "side" => Camera::look_at(
                [cx - 0.1, cy - 0.95, cz + 0.4],
                [cx - 0.1, cy, cz],
                [0.0, 0.0, 1.0],
                self.fovy,
                w,
                h,
            ),
            // The whole arm and the torso, from the front right and above (viewing).
            "overview" => Camera::look_at(
                [cx + 0.75, cy - 1.0, cz + 0.75],
                [cx - 0.3, cy, cz + 0.15],
                [0.0, 0.0, 1.0],
                self.fovy,
                w,
                h,
            ),
            "bird" => Camera::look_at(
                [cx - 0.1, cy, cz + 1.1],
                [cx - 0.1, cy, cz],
                [1.0, 0.0, 0.0],
                self.fovy,
                w,
                h,
            ),
            _ => {
                // On the probe's side, 8 cm back from the face, looking along its axis.
                let tip = scene.tip_pose();
                let eye = arr3(tip * Vector::new(0.03, 0.0, -0.08));
                let target = arr3(tip * Vector::new(0.0, 0.0, 0.05));
                let up = arr3(tip.rotation * Vector::Y);
                Camera::look_at(eye, target, up, self.fovy, w, h)
            }
        }
    }
}

/// Flat colours of the scene's colliders.
pub fn collider_colour(scene: &Scene, handle: ColliderHandle) -> [f32; 3] {
    let s = &scene.world().sets;
    if handle == scene.world().table() {
        [0.55, 0.45, 0.35]
    } else if Some(handle) == scene.torso_collider() {
        [0.92, 0.72, 0.62]
    } else if handle == scene.probe_collider() {
        [0.15, 0.25, 0.6]
    } else if s.colliders[handle]
        .parent()
        .is_some_and(|b| s.bodies[b].is_dynamic() && !scene.arm().links().contains(&b))
    {
        [0.8, 0.15, 0.15]
    } else {
        [0.8, 0.8, 0.82]
    }
}

/// Declare the fields of `observations` and `cameras` on the spec builder.
pub fn declare_fields(
    mut builder: EnvSpecBuilder,
    observations: &[Observation],
    cameras: &[CameraConfig],
    dof: usize,
    particles: usize,
    task_errors: usize,
) -> EnvSpecBuilder {
    for obs in observations {
        let shape: Vec<usize> = match obs {
            Observation::JointPos | Observation::JointVel => vec![dof],
            Observation::ProbePose => vec![7],
            Observation::ProbeVel | Observation::Ft => vec![6],
            Observation::Contact => vec![1],
            Observation::TorsoParticles => vec![particles, 6],
            Observation::TaskErrors => vec![task_errors],
        };
        builder = if *obs == Observation::Contact {
            builder.field(obs.name(), DType::Float32, &shape, Some(0.0), Some(1.0))
        } else {
            builder.f32_field(obs.name(), &shape)
        };
    }
    for cam in cameras {
        if cam.rgb {
            builder = builder.field(
                &format!("{}_rgb", cam.name),
                DType::Uint8,
                &[cam.height, cam.width, 3],
                Some(0.0),
                Some(255.0),
            );
        }
        if cam.depth {
            builder = builder.field(
                &format!("{}_depth", cam.name),
                DType::Float32,
                &[cam.height, cam.width],
                Some(0.0),
                Some(CAMERA_FAR),
            );
        }
    }
    builder
}

/// Write the observation fields (in spec order, starting at field 0); `task_errors`
/// holds the task's errors. Cameras see the torso's collider as last synced; `frame` is
/// the step since the reset (a camera renders when it is a multiple of its `every`).
#[allow(clippy::too_many_arguments)]
pub fn write_fields(
    scene: &Scene,
    observations: &[Observation],
    cameras: &[CameraConfig],
    focus: [f64; 3],
    task_errors: &[f32],
    frame: u64,
    held: &HeldFrames,
    out: &mut EnvOutput<'_>,
) {
    let mut index = 0;
    for obs in observations {
        let field = out.f32_field(index);
        index += 1;
        match obs {
            Observation::JointPos => {
                let q = scene.arm().q(scene.world());
                copy(field, &q);
            }
            Observation::JointVel => {
                let qd = scene.arm().qd(scene.world());
                copy(field, &qd);
            }
            Observation::ProbePose => {
                let tip = scene.tip_pose();
                let p = arr3(tip.translation);
                let r = tip.rotation;
                copy(
                    field,
                    &[
                        p[0], p[1], p[2], r.x as f64, r.y as f64, r.z as f64, r.w as f64,
                    ],
                );
            }
            Observation::ProbeVel => {
                let (v, w) = scene.tip_velocity();
                copy(field, &[v[0], v[1], v[2], w[0], w[1], w[2]]);
            }
            Observation::Ft => copy(field, &scene.ft_reading()),
            Observation::Contact => field[0] = f32::from(u8::from(scene.in_contact())),
            Observation::TorsoParticles => {
                if let Some(torso) = scene.torso() {
                    for (i, row) in field.chunks_exact_mut(6).enumerate() {
                        let p = torso.position(i);
                        let v = torso.velocity(i);
                        copy(row, &[p[0], p[1], p[2], v[0], v[1], v[2]]);
                    }
                }
            }
            Observation::TaskErrors => field.copy_from_slice(task_errors),
        }
    }
    for (c, cam) in cameras.iter().enumerate() {
        let rgb_index = cam.rgb.then_some(index);
        let depth_index = cam.depth.then_some(index + usize::from(cam.rgb));
        index += usize::from(cam.rgb) + usize::from(cam.depth);
        let fresh = frame.is_multiple_of(cam.every.max(1));
        if fresh {
            render_camera(scene, cam, focus, rgb_index, depth_index, out);
        }
        if cam.every > 1 {
            // Between renders the camera repeats its last frame (the record is reused
            // across steps only sometimes, so the frame is kept here).
            let mut held = held.lock().unwrap_or_else(|e| e.into_inner());
            let slot = &mut held[c];
            if let Some(i) = rgb_index {
                if fresh {
                    slot.rgb.clear();
                    slot.rgb.extend_from_slice(out.u8_field(i));
                } else if slot.rgb.len() == out.u8_field(i).len() {
                    out.u8_field(i).copy_from_slice(&slot.rgb);
                }
            }
            if let Some(i) = depth_index {
                if fresh {
                    slot.depth.clear();
                    slot.depth.extend_from_slice(out.f32_field(i));
                } else if slot.depth.len() == out.f32_field(i).len() {
                    out.f32_field(i).copy_from_slice(&slot.depth);
                }
            }
        }
    }
}

/// The last rendered frame of a camera with `every > 1`.
#[derive(Debug, Clone, Default)]
pub struct HeldFrame {
    rgb: Vec<u8>,
    depth: Vec<f32>,
}

/// Held frames, one per camera (see [`CameraConfig::every`]).
pub type HeldFrames = std::sync::Mutex<Vec<HeldFrame>>;

/// Held frames for `cameras`, empty until their first render.
pub fn held_frames(cameras: &[CameraConfig]) -> HeldFrames {
    std::sync::Mutex::new(vec![HeldFrame::default(); cameras.len()])
}

/// Render one camera into its fields.
fn render_camera(
    scene: &Scene,
    cam: &CameraConfig,
    focus: [f64; 3],
    rgb_index: Option<usize>,
    depth_index: Option<usize>,
    out: &mut EnvOutput<'_>,
) {
    let camera = cam.camera(scene, focus);
    let exclude = cam.on_probe().then(|| scene.probe_collider());
    let colour = |h| collider_colour(scene, h);
    // Depth goes through a scratch buffer when both are wanted (two fields of `out`
    // cannot be borrowed at once).
    let mut depth = (rgb_index.is_some() && depth_index.is_some())
        .then(|| vec![0.0f32; cam.width * cam.height]);
    match (rgb_index, depth_index, cam.shading) {
        (Some(r), _, Shading::Smooth) => render_shaded(
            &camera,
            scene,
            exclude,
            depth.as_deref_mut(),
            Some(out.u8_field(r)),
        ),
        (None, Some(d), Shading::Smooth) => {
            render_shaded(&camera, scene, exclude, Some(out.f32_field(d)), None)
        }
        (Some(r), _, Shading::Flat) => camera.render(
            scene.world(),
            exclude,
            &colour,
            depth.as_deref_mut(),
            Some(out.u8_field(r)),
        ),
        (None, Some(d), Shading::Flat) => camera.render(
            scene.world(),
            exclude,
            &colour,
            Some(out.f32_field(d)),
            None,
        ),
        (None, None, _) => {}
    }
    if let (Some(d), Some(depth)) = (depth_index, depth) {
        out.f32_field(d).copy_from_slice(&depth);
    }
}

fn copy(dst: &mut [f32], src: &[f64]) {
    for (d, s) in dst.iter_mut().zip(src) {
        *d = *s as f32;
    }
}
