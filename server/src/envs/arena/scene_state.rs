//! The scene's state for viewers (`scene_state = true`): every collider's shape, part,
//! colour and world pose, the torso's deforming surface mesh with its indentation, and
//! the probe's contact point and force.
//!
//! Four fixed-size float32 fields follow every other field, so a viewer in Python (the
//! rerun logger, the video renderer) sees the same scene as the physics without a second
//! channel: shapes and topology are small enough to ride along every step (≈ 30 KB for
//! the default torso), which keeps the samples self-describing and lets any step be
//! drawn on its own. Off (the default) nothing is declared, written or computed.
//!
//! `scene_colliders` `[colliders, 15]`, one row per collider:
//! `[kind, part, r, g, b, d0, d1, d2, px, py, pz, qx, qy, qz, qw]` — `kind` (see
//! [`ShapeKind`]), `part` (see [`Part`]), the base colour (0–1), the shape's dimensions
//! and its world pose (m; quaternion `x, y, z, w`). Capsules and cylinders are posed with
//! their axis along the pose's z. Unused rows have kind and part −1.
//!
//! `torso_vertices` `[vertices, 4]`: the surface vertices (m, world) and their
//! indentation (m; positive pressed in); `torso_triangles` `[triangles, 3]`: vertex
//! indices (exact in float32). Sized for the largest torso the randomization can draw:
//! the vertices in use are the first `max index + 1` (every one is in a triangle), the
//! rows after them are 0, unused triangles −1 (finite fill: the fields stay inside
//! their observation space).
//!
//! `scene_contact` `[8]`: the contact point (m, world: the skin's centre of pressure on
//! the probe face, else the face centre), the contact force on the probe (N, world,
//! noise-free), 1 while in contact, the axial force (N, positive pressing).

use echogym_protocol::EnvSpecBuilder;
use rapier3d::prelude::*;

use super::part::Part;
use crate::envs::env::EnvOutput;
use crate::sim::scene::Scene;
use crate::sim::torso::{ShellLayout, TorsoParams};
use crate::sim::world::{arr3, vec3};

/// Columns of a `scene_colliders` row.
pub const COLLIDER_COLUMNS: usize = 15;
/// Columns of a `torso_vertices` row.
pub const VERTEX_COLUMNS: usize = 4;
/// Length of `scene_contact`.
pub const CONTACT_LEN: usize = 8;
/// The field names, in order.
pub const SCENE_FIELDS: [&str; 4] = [
    "scene_colliders",
    "torso_vertices",
    "torso_triangles",
    "scene_contact",
];

/// Shape codes of `scene_colliders[:, 0]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShapeKind {
    /// Half extents `d0, d1, d2`.
    Box = 0,
    /// Radius `d0`, half length of the axis segment `d1` (axis: the pose's z).
    Capsule = 1,
    /// Radius `d0`.
    Sphere = 2,
    /// Radius `d0`, half height `d1` (axis: the pose's z).
    Cylinder = 3,
    /// The torso's surface: `torso_vertices` and `torso_triangles`.
    TorsoMesh = 4,
}

/// The sizes of the scene-state fields of one env config.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SceneStateSize {
    /// Rows of `scene_colliders`.
    pub colliders: usize,
    /// Rows of `torso_vertices` (0 without a torso).
    pub vertices: usize,
    /// Rows of `torso_triangles` (0 without a torso).
    pub triangles: usize,
}

impl SceneStateSize {
    /// The sizes for `scene` (as built for the env, task objects included; its colliders
    /// are counted) and its `torso` parameters, the mesh sized for the largest torso the
    /// randomization can draw (`largest_scale`: the upper `torso_scale`).
    pub fn of(scene: &Scene, torso: Option<&TorsoParams>, largest_scale: f64) -> Self {
        let colliders = scene.world().sets.colliders.len();
        let (mut vertices, mut triangles) = (0, 0);
        if let Some(t) = torso {
            for scale in [1.0, largest_scale.max(1.0)] {
                let size = [t.size[0] * scale, t.size[1] * scale, t.size[2]];
                let layout = ShellLayout::new(size, t.center_xy, t.bottom_z, t.spacing);
                let (v, tr) = layout.surface_size();
                vertices = vertices.max(v);
                triangles = triangles.max(tr);
            }
        }
        Self {
            colliders,
            vertices,
            triangles,
        }
    }

    /// Declare the four fields.
    pub fn declare(&self, builder: EnvSpecBuilder) -> EnvSpecBuilder {
        builder
            .f32_field(SCENE_FIELDS[0], &[self.colliders, COLLIDER_COLUMNS])
            .f32_field(SCENE_FIELDS[1], &[self.vertices, VERTEX_COLUMNS])
            .f32_field(SCENE_FIELDS[2], &[self.triangles, 3])
            .f32_field(SCENE_FIELDS[3], &[CONTACT_LEN])
    }
}

/// Write the four fields, `first` being the index of `scene_colliders`.
pub fn write_scene_state(scene: &Scene, first: usize, out: &mut EnvOutput<'_>) {
    write_colliders(scene, out.f32_field(first));
    let torso = scene.torso();
    let vertices = out.f32_field(first + 1);
    vertices.fill(0.0);
    if let Some(torso) = torso {
        let top = torso.params().top_z();
        let layout = torso.layout();
        let u = torso.displacements();
        let rows = vertices.chunks_exact_mut(VERTEX_COLUMNS);
        for (i, (row, p)) in rows.zip(torso.surface_vertices()).enumerate() {
            let indentation = if i < layout.top_len() {
                top - p[2]
            } else if i < layout.len() {
                -u[i]
            } else {
                0.0
            };
            row.copy_from_slice(&[p[0] as f32, p[1] as f32, p[2] as f32, indentation as f32]);
        }
    }
    let triangles = out.f32_field(first + 2);
    triangles.fill(-1.0);
    if let Some(torso) = torso {
        for (row, t) in triangles.chunks_exact_mut(3).zip(torso.surface_triangles()) {
            row.copy_from_slice(&t.map(|v| v as f32));
        }
    }
    let point = contact_point(scene);
    let f = scene.contact_force();
    let contact = out.f32_field(first + 3);
    let values = [
        point[0],
        point[1],
        point[2],
        f[0],
        f[1],
        f[2],
        f64::from(u8::from(scene.in_contact())),
        scene.axial_contact_force(),
    ];
    for (d, s) in contact.iter_mut().zip(values) {
        *d = s as f32;
    }
}

fn write_colliders(scene: &Scene, field: &mut [f32]) {
    field.fill(0.0);
    let mut rows = field.chunks_exact_mut(COLLIDER_COLUMNS);
    for (handle, collider) in scene.world().sets.colliders.iter() {
        let Some(row) = rows.next() else {
            return;
        };
        let part = Part::of(scene, handle);
        let (kind, dims, local) = shape_of(collider.shape());
        let (dims, pose) = match kind {
            Some(kind) => (dims, (*collider.position() * local, kind as i32 as f32)),
            // Anything else is drawn as its world bounding box.
            None => {
                let aabb = collider.compute_aabb();
                let centre = (aabb.mins + aabb.maxs) * 0.5;
                let half = (aabb.maxs - aabb.mins) * 0.5;
                (
                    [half.x, half.y, half.z],
                    (Pose::from_translation(centre), ShapeKind::Box as i32 as f32),
                )
            }
        };
        let (pose, kind) = pose;
        let (t, q) = (pose.translation, pose.rotation);
        let colour = part.colour();
        row.copy_from_slice(&[
            kind,
            part.code(),
            colour[0],
            colour[1],
            colour[2],
            dims[0],
            dims[1],
            dims[2],
            t.x,
            t.y,
            t.z,
            q.x,
            q.y,
            q.z,
            q.w,
        ]);
    }
    for row in rows {
        row[0] = -1.0;
        row[1] = -1.0;
    }
}

/// The kind, dimensions and pose in the collider's frame of a shape (`None`: not one of
/// the [`ShapeKind`]s).
fn shape_of(shape: &dyn Shape) -> (Option<ShapeKind>, [f32; 3], Pose) {
    if let Some(b) = shape.as_cuboid() {
        let h = b.half_extents;
        return (Some(ShapeKind::Box), [h.x, h.y, h.z], Pose::IDENTITY);
    }
    if let Some(c) = shape.as_capsule() {
        let (a, b) = (c.segment.a, c.segment.b);
        let axis = b - a;
        let half = axis.length() * 0.5;
        let rotation = if half > 0.0 {
            Rotation::from_rotation_arc(Vector::Z, axis / (2.0 * half))
        } else {
            Rotation::IDENTITY
        };
        return (
            Some(ShapeKind::Capsule),
            [c.radius, half, 0.0],
            Pose::from_parts((a + b) * 0.5, rotation),
        );
    }
    if let Some(s) = shape.as_ball() {
        return (
            Some(ShapeKind::Sphere),
            [s.radius, 0.0, 0.0],
            Pose::IDENTITY,
        );
    }
    if let Some(c) = shape.as_cylinder() {
        return (
            Some(ShapeKind::Cylinder),
            [c.radius, c.half_height, 0.0],
            Pose::from_rotation(Rotation::from_rotation_arc(Vector::Z, Vector::Y)),
        );
    }
    if shape.as_trimesh().is_some() {
        return (Some(ShapeKind::TorsoMesh), [0.0; 3], Pose::IDENTITY);
    }
    (None, [0.0; 3], Pose::IDENTITY)
}

/// Where the probe touches: the skin's centre of pressure on the face plane, else the
/// face centre [m, world].
fn contact_point(scene: &Scene) -> [f64; 3] {
    let tip = scene.tip_pose();
    let centre = arr3(tip.translation);
    let wrench = scene.torso_wrench();
    let f = vec3(wrench.force);
    let f2 = f.length_squared();
    if !wrench.in_contact() || f2 < 1e-12 {
        return centre;
    }
    // The wrench's line of action (torque about the probe link's centre of mass), cut
    // with the face plane.
    let com = scene.world().sets.bodies[scene.arm().last_link()].center_of_mass();
    let on_line = com + f.cross(vec3(wrench.torque)) / f2;
    let axis = tip.rotation * Vector::Z;
    let along = f.dot(axis);
    if along.abs() < 1e-9 {
        return centre;
    }
    let s = (tip.translation - on_line).dot(axis) / along;
    arr3(on_line + f * s)
}
