//! [`ShellLayout`]: where the torso's particles sit, which way they slide, what area they
//! stand for, and who their neighbours are.
//!
//! Particles cover the shell of the box except its bottom, which rests on the table and
//! does not move: a grid on the top face (`nx × ny`, normal +z), then rings around the
//! sides at the heights between bottom and top (outward horizontal normals, diagonal at
//! the corners). Each particle slides along its rest normal only (a 1-DoF slider, as in
//! the seed's composite), so the state is one displacement per particle.

/// Particle geometry and connectivity of a box-shaped torso shell.
#[derive(Debug, Clone)]
pub struct ShellLayout {
    /// Top grid size in x.
    pub nx: usize,
    /// Top grid size in y.
    pub ny: usize,
    /// Top grid spacing in x and y \[m\].
    pub h: [f64; 2],
    /// Number of side rings.
    pub rings: usize,
    /// Rest positions (world) \[m\].
    pub rest: Vec<[f64; 3]>,
    /// Unit slide directions (outward rest normals).
    pub normal: Vec<[f64; 3]>,
    /// Surface area each particle stands for \[m²\].
    pub area: Vec<f64>,
    /// Undirected neighbour pairs `(i, j, weight)`; weight scales the edge spring to
    /// keep the membrane tension uniform where spacings differ.
    pub edges: Vec<(usize, usize, f64)>,
    /// Per particle: weight of a link to the fixed bottom (side particles of the lowest
    /// ring), else 0.
    pub ground: Vec<f64>,
    /// The top grid's boundary `(i, j)`, counter-clockwise; ring particle `k` of ring `r`
    /// is `top_len + r·boundary.len() + k` and stands below boundary point `k`.
    pub boundary: Vec<(usize, usize)>,
    /// World z of the fixed bottom edge \[m\].
    pub bottom_z: f64,
}

impl ShellLayout {
    /// The same layout with every link's weight scaled by the local stiffness
    /// `scale(x, y)` (a neighbour link by the mean of its ends, a ground link by its
    /// particle's), so a stiffer or softer patch of tissue is so in all its elastic
    /// elements and not only in its particles' own springs: with the springs alone a
    /// patch could not soften below ≈ 0.73 of its neighbours' stiffness under the probe.
    pub fn with_stiffness_field(mut self, scale: impl Fn([f64; 2]) -> f64) -> Self {
        let local: Vec<f64> = self.rest.iter().map(|p| scale([p[0], p[1]])).collect();
        for (i, j, w) in &mut self.edges {
            *w *= 0.5 * (local[*i] + local[*j]);
        }
        for (g, s) in self.ground.iter_mut().zip(&local) {
            *g *= s;
        }
        self
    }

    /// Lay out a box of `size` with its bottom centre at `(cx, cy, bottom_z)` and a
    /// particle spacing close to `spacing`.
    pub fn new(size: [f64; 3], center_xy: [f64; 2], bottom_z: f64, spacing: f64) -> Self {
        let cells = |len: f64| ((len / spacing).round() as usize).max(2);
        let (cx, cy) = (cells(size[0]), cells(size[1]));
        let (nx, ny) = (cx + 1, cy + 1);
        let h = [size[0] / cx as f64, size[1] / cy as f64];
        let rings_cells = cells(size[2]);
        let hz = size[2] / rings_cells as f64;
        let rings = rings_cells - 1;
        let x0 = center_xy[0] - size[0] / 2.0;
        let y0 = center_xy[1] - size[1] / 2.0;
        let top = bottom_z + size[2];

        let mut rest = Vec::new();
        let mut normal = Vec::new();
        let mut area = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                rest.push([x0 + i as f64 * h[0], y0 + j as f64 * h[1], top]);
                normal.push([0.0, 0.0, 1.0]);
                let wx = if i == 0 || i == nx - 1 { 0.5 } else { 1.0 };
                let wy = if j == 0 || j == ny - 1 { 0.5 } else { 1.0 };
                area.push(wx * wy * h[0] * h[1]);
            }
        }
        let mut edges = Vec::new();
        let top_index = |i: usize, j: usize| j * nx + i;
        // A grid edge spring k·(h_perp/h_along) gives membrane tension k per unit length.
        for j in 0..ny {
            for i in 0..nx {
                if i + 1 < nx {
                    edges.push((top_index(i, j), top_index(i + 1, j), h[1] / h[0]));
                }
                if j + 1 < ny {
                    edges.push((top_index(i, j), top_index(i, j + 1), h[0] / h[1]));
                }
            }
        }

        // The top grid's boundary, walked counter-clockwise, with each step's length.
        let mut boundary = Vec::new();
        for i in 0..nx - 1 {
            boundary.push((i, 0));
        }
        for j in 0..ny - 1 {
            boundary.push((nx - 1, j));
        }
        for i in (1..nx).rev() {
            boundary.push((i, ny - 1));
        }
        for j in (1..ny).rev() {
            boundary.push((0, j));
        }
        let outward = |i: usize, j: usize| -> [f64; 3] {
            let nx_: f64 = if i == 0 {
                -1.0
            } else if i == nx - 1 {
                1.0
            } else {
                0.0
            };
            let ny_ = if j == 0 {
                -1.0
            } else if j == ny - 1 {
                1.0
            } else {
                0.0
            };
            let len = (nx_ * nx_ + ny_ * ny_).sqrt();
            [nx_ / len, ny_ / len, 0.0]
        };
        let along = |i: usize, j: usize, k: usize| -> f64 {
            // Spacing along the perimeter between boundary points k and k+1.
            let (a, b) = (boundary[k], boundary[(k + 1) % boundary.len()]);
            let _ = (i, j);
            if a.0 != b.0 { h[0] } else { h[1] }
        };
        let count = boundary.len();
        let ring_start = rest.len();
        for r in 0..rings {
            let z = bottom_z + (r + 1) as f64 * hz;
            for (k, &(i, j)) in boundary.iter().enumerate() {
                let p = rest[top_index(i, j)];
                rest.push([p[0], p[1], z]);
                normal.push(outward(i, j));
                let prev = along(i, j, (k + count - 1) % count);
                let next = along(i, j, k);
                area.push(0.5 * (prev + next) * hz);
            }
        }
        let ring_index = |r: usize, k: usize| ring_start + r * count + k;
        let mut ground = vec![0.0; rest.len()];
        for r in 0..rings {
            for (k, &(i, j)) in boundary.iter().enumerate() {
                let step = along(i, j, k);
                edges.push((ring_index(r, k), ring_index(r, (k + 1) % count), hz / step));
                let width = 0.5 * (step + along(i, j, (k + count - 1) % count));
                let vertical = width / hz;
                if r + 1 < rings {
                    edges.push((ring_index(r, k), ring_index(r + 1, k), vertical));
                } else {
                    edges.push((ring_index(r, k), top_index(i, j), vertical));
                }
                if r == 0 {
                    ground[ring_index(r, k)] = vertical;
                }
            }
        }
        Self {
            nx,
            ny,
            h,
            rings,
            rest,
            normal,
            area,
            edges,
            ground,
            boundary,
            bottom_z,
        }
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.rest.len()
    }

    /// True when there are no particles (never, for a valid box).
    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// Number of particles on the top face (they come first).
    pub fn top_len(&self) -> usize {
        self.nx * self.ny
    }

    /// Vertex and triangle counts of the torso's surface mesh
    /// ([`crate::sim::torso::Torso::surface_triangles`]).
    pub fn surface_size(&self) -> (usize, usize) {
        let band = self.boundary.len();
        let vertices = self.len() + band;
        let triangles = 2 * (self.nx - 1) * (self.ny - 1) + 2 * band * (self.rings + 1);
        (vertices, triangles)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_box_counts_and_areas() {
        let layout = ShellLayout::new([0.28, 0.35, 0.105], [0.0, 0.0], 0.8, 0.0175);
        assert_eq!((layout.nx, layout.ny), (17, 21));
        assert_eq!(layout.rings, 5);
        let perimeter_points = 2 * (16 + 20);
        assert_eq!(layout.len(), 17 * 21 + 5 * perimeter_points);
        let top: f64 = layout.area[..layout.top_len()].iter().sum();
        assert!((top - 0.28 * 0.35).abs() < 1e-12, "top area {top}");
        let sides: f64 = layout.area[layout.top_len()..].iter().sum();
        let expected = 2.0 * (0.28 + 0.35) * 0.105 * 5.0 / 6.0;
        assert!(
            (sides - expected).abs() < 1e-9,
            "side area {sides} vs {expected}"
        );
        for n in &layout.normal {
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            assert!((len - 1.0).abs() < 1e-12);
        }
    }
}
