//! The smooth skin of the top face: a uniform cubic B-spline surface over the top
//! particle grid. The probe touches this surface, not the particles, so it feels no grid:
//! B-spline weights are smooth (C²) and sum to one everywhere, so a contact force is
//! spread over the 4 × 4 nearest particles with total force conserved.

/// Up to 16 `(particle, weight)` pairs of one skin point.
pub type SkinWeights = [(usize, f64); 16];

/// Cubic B-spline basis at parameter `t ∈ [0, 1]` for nodes `c-1, c, c+1, c+2`.
fn basis(t: f64) -> [f64; 4] {
    let t2 = t * t;
    let t3 = t2 * t;
    let s = 1.0 - t;
    [
        s * s * s / 6.0,
        (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0,
        (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
        t3 / 6.0,
    ]
}

/// Cell index and local parameter of coordinate `x` on an axis of `n` nodes starting at
/// `origin` with spacing `h` (clamped to the grid).
fn locate(x: f64, origin: f64, h: f64, n: usize) -> (usize, f64) {
    let xi = ((x - origin) / h).clamp(0.0, (n - 1) as f64);
    let cell = (xi.floor() as usize).min(n - 2);
    (cell, xi - cell as f64)
}

/// The top-face skin of an `nx × ny` grid with origin `(x0, y0)` and spacing `h`.
#[derive(Debug, Clone)]
pub struct Skin {
    nx: usize,
    ny: usize,
    origin: [f64; 2],
    h: [f64; 2],
}

impl Skin {
    /// A skin over the grid (particle `j * nx + i` at `origin + (i·hx, j·hy)`).
    pub fn new(nx: usize, ny: usize, origin: [f64; 2], h: [f64; 2]) -> Self {
        Self { nx, ny, origin, h }
    }

    /// Whether `(x, y)` lies over the top face.
    pub fn covers(&self, x: f64, y: f64) -> bool {
        let (x1, y1) = (
            self.origin[0] + (self.nx - 1) as f64 * self.h[0],
            self.origin[1] + (self.ny - 1) as f64 * self.h[1],
        );
        x >= self.origin[0] && x <= x1 && y >= self.origin[1] && y <= y1
    }

    /// Weights of the skin point over `(x, y)`: the skin's displacement there is
    /// `Σ w · u[particle]`. Nodes beyond the grid clamp to the edge (weights still sum
    /// to one).
    pub fn weights(&self, x: f64, y: f64) -> SkinWeights {
        let (ci, tx) = locate(x, self.origin[0], self.h[0], self.nx);
        let (cj, ty) = locate(y, self.origin[1], self.h[1], self.ny);
        let (bx, by) = (basis(tx), basis(ty));
        let clamp = |c: usize, k: usize, n: usize| (c + k).saturating_sub(1).min(n - 1);
        let mut out = [(0, 0.0); 16];
        for (b, wy) in by.iter().enumerate() {
            let j = clamp(cj, b, self.ny);
            for (a, wx) in bx.iter().enumerate() {
                let i = clamp(ci, a, self.nx);
                out[b * 4 + a] = (j * self.nx + i, wx * wy);
            }
        }
        out
    }

    /// Skin displacement over `(x, y)` for particle displacements `u`.
    pub fn displacement(&self, u: &[f64], x: f64, y: f64) -> f64 {
        self.weights(x, y).iter().map(|&(i, w)| w * u[i]).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_sum_to_one_and_reproduce_planes() {
        let skin = Skin::new(5, 4, [0.0, 0.0], [0.1, 0.2]);
        // A linear field away from the clamped border is reproduced exactly.
        let u: Vec<f64> = (0..20)
            .map(|k| 0.3 * (k % 5) as f64 + 0.7 * (k / 5) as f64)
            .collect();
        for &(x, y) in &[(0.17, 0.31), (0.2, 0.3), (0.25, 0.35)] {
            let w = skin.weights(x, y);
            let sum: f64 = w.iter().map(|p| p.1).sum();
            assert!((sum - 1.0).abs() < 1e-12);
            let expected = 0.3 * x / 0.1 + 0.7 * y / 0.2;
            assert!((skin.displacement(&u, x, y) - expected).abs() < 1e-12);
        }
        let w = skin.weights(-1.0, 5.0);
        assert!((w.iter().map(|p| p.1).sum::<f64>() - 1.0).abs() < 1e-12);
    }
}
