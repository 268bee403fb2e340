//! Shaded camera images for viewing (a camera's `shading = "smooth"`): the same one ray
//! per pixel through rapier's query pipeline as the cheap observation path, shaded like
//! a viewer's default scene — a key light with shadows (one more ray), a headlight fill,
//! sky ambient and a highlight; the torso's normals interpolated from its vertices so
//! the skin reads smooth; each part in its own colour ([`Part::colour`]) with arm links
//! alternating; a 10 cm checker on the table and a sky gradient behind.
//!
//! Rendered in Rust, next to the scene, because the ray casts already exist there and
//! the image then rides the shared-memory sample like every camera (vector envs, video
//! wrappers and torchrl see it without a copy); cost per frame in
//! docs/results/benchmarks.md.

use rapier3d::prelude::*;

use super::part::Part;
use crate::sim::camera::Camera;
use crate::sim::scene::Scene;
use crate::sim::vec3::{cross, normalize};
use crate::sim::world::vec3;

/// Direction towards the key light (world; from above, front left of the robot).
const KEY_LIGHT: [f64; 3] = [0.45, -0.55, 1.0];
/// How far a shadow ray looks for an occluder \[m\].
const SHADOW_REACH: Real = 3.0;

/// Render `camera`'s view of `scene` into `rgb` (`h × w × 3` uint8) and/or `depth`
/// (metres along the axis), ignoring `exclude`.
pub fn render_shaded(
    camera: &Camera,
    scene: &Scene,
    exclude: Option<ColliderHandle>,
    mut depth: Option<&mut [f32]>,
    mut rgb: Option<&mut [u8]>,
) {
    let pipeline = scene.world().query_pipeline(exclude);
    let torso = scene.torso_collider();
    let skin = torso.and_then(|h| {
        scene
            .world()
            .sets
            .colliders
            .get(h)?
            .shape()
            .as_trimesh()
            .map(SmoothMesh::new)
    });
    let light = vec3(normalize(KEY_LIGHT));
    let right = cross(camera.forward, camera.up);
    let origin = vec3(camera.eye);
    for row in 0..camera.height {
        for col in 0..camera.width {
            let (dir, cos) = camera.ray(right, row, col);
            let d = vec3(dir);
            let ray = Ray::new(origin, d);
            let hit = pipeline.cast_ray_and_get_normal(&ray, camera.far as Real, true);
            let k = row * camera.width + col;
            if let Some(out) = depth.as_deref_mut() {
                out[k] = hit.map_or(camera.far as f32, |(_, h)| {
                    (h.time_of_impact as f64 * cos) as f32
                });
            }
            let Some(out) = rgb.as_deref_mut() else {
                continue;
            };
            let colour = match hit {
                None => sky(d),
                Some((handle, h)) => {
                    let point = ray.point_at(h.time_of_impact);
                    let part = Part::of(scene, handle);
                    let mut n = h.normal;
                    if let (Part::Torso, Some(mesh)) = (part, &skin) {
                        n = mesh.normal_at(h.subshape as usize, point, n);
                    }
                    if n.dot(d) > 0.0 {
                        n = -n;
                    }
                    let mut base = part.colour();
                    if part == Part::Table {
                        base = checker(base, point);
                    }
                    let lit = n.dot(light).max(0.0);
                    let shadowed = lit > 0.0
                        && pipeline
                            .cast_ray(&Ray::new(point + n * 1e-3, light), SHADOW_REACH, true)
                            .is_some();
                    let key = if shadowed { 0.0 } else { 0.62 * lit };
                    let fill = 0.22 * (-n.dot(d)).max(0.0);
                    let ambient = 0.16 + 0.08 * n.z;
                    let half = (light - d).normalize();
                    let gloss = if matches!(part, Part::Probe | Part::Link(_) | Part::Object) {
                        0.25
                    } else {
                        0.06
                    };
                    let highlight = if shadowed {
                        0.0
                    } else {
                        gloss * n.dot(half).max(0.0).powi(32)
                    };
                    let light = (key + fill + ambient) as f32;
                    base.map(|b| b * light + highlight as f32)
                }
            };
            for ch in 0..3 {
                // Shade in linear light, store gamma-encoded (sRGB-ish).
                let v = colour[ch].clamp(0.0, 1.0).powf(1.0 / 2.2);
                out[3 * k + ch] = (v * 255.0).round() as u8;
            }
        }
    }
}

/// Vertex normals of the torso's surface for interpolation across its triangles.
struct SmoothMesh<'a> {
    mesh: &'a TriMesh,
    normals: Vec<Vector>,
}

impl<'a> SmoothMesh<'a> {
    fn new(mesh: &'a TriMesh) -> Self {
        let vertices = mesh.vertices();
        let mut normals = vec![Vector::ZERO; vertices.len()];
        for tri in mesh.indices() {
            let [a, b, c] = tri.map(|v| vertices[v as usize]);
            // Area-weighted face normal; consistent winding keeps the sum coherent.
            let n = (b - a).cross(c - a);
            for &v in tri {
                normals[v as usize] += n;
            }
        }
        for n in &mut normals {
            *n = n.normalize_or_zero();
        }
        Self { mesh, normals }
    }

    /// The interpolated normal at `point` on triangle `tri`, on the side of `face`.
    fn normal_at(&self, tri: usize, point: Vector, face: Vector) -> Vector {
        let Some(idx) = self.mesh.indices().get(tri) else {
            return face;
        };
        let v = self.mesh.vertices();
        let [a, b, c] = idx.map(|i| v[i as usize]);
        let (e0, e1, e2) = (b - a, c - a, point - a);
        let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
        let (d20, d21) = (e2.dot(e0), e2.dot(e1));
        let denom = d00 * d11 - d01 * d01;
        if denom.abs() < 1e-20 {
            return face;
        }
        let wb = (d11 * d20 - d01 * d21) / denom;
        let wc = (d00 * d21 - d01 * d20) / denom;
        let wa = 1.0 - wb - wc;
        let [na, nb, nc] = idx.map(|i| self.normals[i as usize]);
        let n = (na * wa + nb * wb + nc * wc).normalize_or_zero();
        if n == Vector::ZERO {
            face
        } else if n.dot(face) < 0.0 {
            -n
        } else {
            n
        }
    }
}

/// Background: a sky gradient from the horizon up.
fn sky(d: Vector) -> [f32; 3] {
    let t = d.z.clamp(-0.2, 1.0) * 0.5 + 0.5;
    let (low, high) = ([0.80, 0.83, 0.87], [0.42, 0.55, 0.72]);
    [0, 1, 2].map(|i| low[i] + (high[i] - low[i]) * t)
}

/// A 10 cm checker on the table, so motion and distance read.
fn checker(base: [f32; 3], p: Vector) -> [f32; 3] {
    let cell = |v: Real| (v / 0.1).floor() as i64;
    let dark = (cell(p.x) + cell(p.y)).rem_euclid(2) == 0;
    if dark { base.map(|b| b * 0.82) } else { base }
}
