//! The implicit (backward-Euler) step of the particle system, solved matrix-free by
//! Jacobi-preconditioned conjugate gradients.
//!
//! With particle displacements `u`, velocities `v`, masses `M` and the linearised force
//! `f(u + dt·v', v') ≈ f₀ - K·dt·v' - C·(v' - v)`, one step solves the symmetric positive
//! definite system
//! ```text
//! (M + dt·C + dt²·K) · v' = M·v + dt·(f₀ + C·v),        u' = u + dt·v'
//! ```
//! where `K` and `C` gather the laws' diagonal terms, the neighbour Laplacian, the ground
//! links, the rank-one volume term and one rank-one term per active contact sample.
//! Backward Euler is unconditionally stable for these terms, which is what lets stiffness
//! ×5 and a 50 N press run at 2 ms.
//!
//! CG is most of a torso step in contact (≈ 85 % of a calibration replay), so `A·p` is
//! applied by rows: each particle gathers its neighbours ([`Links`]) instead of an
//! edge-by-edge scatter whose stores each wait for the last; `pᵀ·A·p` and the residual's
//! norms are summed in the passes that produce them, in four interleaved partial sums,
//! and the preconditioner is an inverse diagonal (a product, not a division, per entry).

use super::skin::SkinWeights;

/// An active contact sample as seen by the solver: skin weights and its `dt·c + dt²·k`.
#[derive(Debug, Clone)]
pub struct ContactRow {
    /// Skin weights of the sample.
    pub weights: SkinWeights,
    /// Coefficient of `w·wᵀ` in the system matrix.
    pub coef: f64,
}

/// Neighbour links, as an edge list (for the factor's pattern) and by rows.
///
/// The rows are padded to one width (the largest degree; self-links of weight 0 fill
/// the gaps), so the gather's inner loop has one trip count and no mispredicted exit:
/// with variable-length rows it cost more than the arithmetic.
#[derive(Debug, Clone, Default)]
pub struct Links {
    edges: Vec<(usize, usize, f64)>,
    /// Links per row (the largest degree).
    width: usize,
    /// Row `i`'s links are `i·width..(i + 1)·width` of `other` and `weight`.
    other: Vec<u32>,
    weight: Vec<f64>,
    /// Sum of row `i`'s link weights.
    weight_sum: Vec<f64>,
}

impl Links {
    /// Links of `n` particles from undirected `(i, j, weight)` edges.
    ///
    /// # Panics
    /// If an edge names a particle `≥ n` or `n` does not fit in `u32`.
    pub fn new(n: usize, edges: &[(usize, usize, f64)]) -> Self {
        let index = |i: usize| u32::try_from(i).expect("particle index fits u32");
        let mut degree = vec![0usize; n];
        for &(i, j, _) in edges {
            assert!(i < n && j < n, "edge ({i}, {j}) outside {n} particles");
            degree[i] += 1;
            degree[j] += 1;
        }
        let width = degree.iter().copied().max().unwrap_or(0).max(1);
        let mut other: Vec<u32> = (0..n)
            .flat_map(|i| std::iter::repeat_n(index(i), width))
            .collect();
        let mut weight = vec![0.0; n * width];
        let mut weight_sum = vec![0.0; n];
        degree.fill(0);
        for &(i, j, w) in edges {
            for (a, b) in [(i, j), (j, i)] {
                let at = a * width + degree[a];
                degree[a] += 1;
                other[at] = index(b);
                weight[at] = w;
                weight_sum[a] += w;
            }
        }
        Self {
            edges: edges.to_vec(),
            width,
            other,
            weight,
            weight_sum,
        }
    }

    /// The undirected edges `(i, j, weight)`.
    pub fn edges(&self) -> &[(usize, usize, f64)] {
        &self.edges
    }
}

/// The system matrix, applied without being formed.
pub struct System<'a> {
    /// Diagonal part: masses, laws, ground links (already scaled by dt).
    pub diag: &'a [f64],
    /// Neighbour links.
    pub links: &'a Links,
    /// `dt·c_edge + dt²·k_edge` per unit edge weight.
    pub edge_coef: f64,
    /// Areas for the volume term and its `dt²·K_b/V` coefficient.
    pub volume: Option<(&'a [f64], f64)>,
    /// Active contact rows.
    pub contacts: &'a [ContactRow],
}

impl System<'_> {
    /// `y = A·x`.
    pub fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.apply_dot(x, y);
    }

    /// `y = A·x`; returns `xᵀ·A·x`.
    fn apply_dot(&self, x: &[f64], y: &mut [f64]) -> f64 {
        let n = self.diag.len();
        let l = self.links;
        let (x, y) = (&x[..n], &mut y[..n]);
        let c = self.edge_coef;
        let rows = l
            .other
            .chunks_exact(l.width)
            .zip(l.weight.chunks_exact(l.width));
        if l.width == 4 {
            // The layout's grid: a fixed-size gather summed as a tree (no add chain).
            for (i, (other, weight)) in rows.enumerate().take(n) {
                let g = |k: usize| weight[k] * x[other[k] as usize];
                let gathered = (g(0) + g(1)) + (g(2) + g(3));
                y[i] = (self.diag[i] + c * l.weight_sum[i]) * x[i] - c * gathered;
            }
        } else {
            for (i, (other, weight)) in rows.enumerate().take(n) {
                let gathered: f64 = other
                    .iter()
                    .zip(weight)
                    .map(|(&j, &w)| w * x[j as usize])
                    .sum();
                y[i] = (self.diag[i] + c * l.weight_sum[i]) * x[i] - c * gathered;
            }
        }
        if let Some((area, coef)) = self.volume {
            let s = coef * dot(&area[..n], x);
            for (y, a) in y.iter_mut().zip(area) {
                *y += s * a;
            }
        }
        for row in self.contacts {
            let s = row.coef * row.weights.iter().map(|&(i, w)| w * x[i]).sum::<f64>();
            for &(i, w) in &row.weights {
                y[i] += s * w;
            }
        }
        dot(x, y)
    }

    /// The diagonal of `A` (for the Jacobi preconditioner).
    pub fn diagonal(&self, out: &mut [f64]) {
        for ((o, d), w) in out.iter_mut().zip(self.diag).zip(&self.links.weight_sum) {
            *o = d + self.edge_coef * w;
        }
        if let Some((area, coef)) = self.volume {
            for (o, a) in out.iter_mut().zip(area) {
                *o += coef * a * a;
            }
        }
        for row in self.contacts {
            for &(i, w) in &row.weights {
                out[i] += row.coef * w * w;
            }
        }
    }
}

/// `Σ aᵢ·bᵢ` in four interleaved partial sums (independent add chains).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut lanes = [0.0; 4];
    let (a4, b4) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = a4
        .remainder()
        .iter()
        .zip(b4.remainder())
        .map(|(a, b)| a * b)
        .sum();
    for (a, b) in a4.zip(b4) {
        for k in 0..4 {
            lanes[k] += a[k] * b[k];
        }
    }
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]) + tail
}

/// Scratch vectors reused across steps (no allocation per step).
#[derive(Debug, Clone, Default)]
pub struct Workspace {
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    ap: Vec<f64>,
    /// Inverse of `A`'s diagonal (the Jacobi preconditioner).
    inverse_diag: Vec<f64>,
}

/// Solve `A·x = b` by preconditioned CG, starting from `x`. Stops when the residual norm
/// falls below `tolerance · |b|` or after `max_iterations`; returns the iterations used.
pub fn conjugate_gradient(
    system: &System<'_>,
    b: &[f64],
    x: &mut [f64],
    tolerance: f64,
    max_iterations: usize,
    ws: &mut Workspace,
) -> usize {
    let n = b.len();
    for v in [
        &mut ws.r,
        &mut ws.z,
        &mut ws.p,
        &mut ws.ap,
        &mut ws.inverse_diag,
    ] {
        v.resize(n, 0.0);
    }
    system.diagonal(&mut ws.inverse_diag);
    for d in &mut ws.inverse_diag {
        *d = 1.0 / *d;
    }
    system.apply(x, &mut ws.ap);
    let mut rz = 0.0;
    let mut rr = 0.0;
    for (((r, z), p), (b, (ap, d))) in
        ws.r.iter_mut()
            .zip(ws.z.iter_mut())
            .zip(ws.p.iter_mut())
            .zip(b.iter().zip(ws.ap.iter().zip(&ws.inverse_diag)))
    {
        *r = b - ap;
        *z = *r * d;
        *p = *z;
        rz += *r * *z;
        rr += *r * *r;
    }
    let b_norm = b.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300);
    let threshold = (tolerance * b_norm).powi(2);
    for iteration in 0..max_iterations {
        if rr <= threshold {
            return iteration;
        }
        let pap = system.apply_dot(&ws.p, &mut ws.ap);
        if pap <= 0.0 {
            return iteration;
        }
        let alpha = rz / pap;
        let (mut rz_next, mut rr_next) = (0.0, 0.0);
        for ((x, p), ((r, ap), (z, d))) in x.iter_mut().zip(&ws.p).zip(
            ws.r.iter_mut()
                .zip(&ws.ap)
                .zip(ws.z.iter_mut().zip(&ws.inverse_diag)),
        ) {
            *x += alpha * p;
            *r -= alpha * ap;
            *z = *r * d;
            rz_next += *r * *z;
            rr_next += *r * *r;
        }
        let beta = rz_next / rz;
        (rz, rr) = (rz_next, rr_next);
        for (p, z) in ws.p.iter_mut().zip(&ws.z) {
            *p = z + beta * *p;
        }
    }
    max_iterations
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Diagonal, edges, areas and contact rows of a test system.
    type Parts = (
        Vec<f64>,
        Vec<(usize, usize, f64)>,
        Vec<f64>,
        Vec<ContactRow>,
    );

    /// A small system with rows of 2 to 5 links, a volume term and two contact rows.
    fn parts() -> Parts {
        let n = 9;
        let diag: Vec<f64> = (0..n).map(|i| 1.0 + 0.1 * i as f64).collect();
        let mut edges: Vec<(usize, usize, f64)> = (0..n - 1)
            .map(|i| (i, i + 1, 0.5 + 0.05 * i as f64))
            .collect();
        edges.extend([
            (0, 4, 0.7),
            (0, 8, 0.3),
            (2, 6, 1.1),
            (0, 2, 0.4),
            (0, 6, 0.2),
        ]);
        let area: Vec<f64> = (0..n).map(|i| 0.01 * (1 + i % 3) as f64).collect();
        let row = |first: usize, coef: f64| {
            let mut weights = [(0, 0.0); 16];
            for (k, w) in weights.iter_mut().enumerate().take(4) {
                *w = (first + k, 0.25 + 0.05 * k as f64);
            }
            ContactRow { weights, coef }
        };
        (diag, edges, area, vec![row(1, 40.0), row(3, 25.0)])
    }

    /// The matrix formed entry by entry from the same terms.
    fn dense(system: &System<'_>, n: usize) -> Vec<Vec<f64>> {
        let mut a = vec![vec![0.0; n]; n];
        for (i, d) in system.diag.iter().enumerate() {
            a[i][i] += d;
        }
        for &(i, j, w) in system.links.edges() {
            let c = system.edge_coef * w;
            a[i][i] += c;
            a[j][j] += c;
            a[i][j] -= c;
            a[j][i] -= c;
        }
        if let Some((area, coef)) = system.volume {
            for i in 0..n {
                for j in 0..n {
                    a[i][j] += coef * area[i] * area[j];
                }
            }
        }
        for row in system.contacts {
            for &(i, wi) in &row.weights {
                for &(j, wj) in &row.weights {
                    a[i][j] += row.coef * wi * wj;
                }
            }
        }
        a
    }

    #[test]
    fn rows_apply_the_same_matrix_as_its_terms() {
        let (diag, edges, area, contacts) = parts();
        let n = diag.len();
        let links = Links::new(n, &edges);
        // Grid rows (width 4) take their own path; check both.
        let grid_edges: Vec<(usize, usize, f64)> = edges
            .iter()
            .copied()
            .filter(|&(i, j, _)| (i, j) != (0, 6))
            .collect();
        let grid = Links::new(n, &grid_edges);
        assert_eq!((links.width, grid.width), (5, 4));
        for links in [&links, &grid] {
            let system = System {
                diag: &diag,
                links,
                edge_coef: 3.0,
                volume: Some((&area, 50.0)),
                contacts: &contacts,
            };
            let a = dense(&system, n);
            let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).sin()).collect();
            let mut y = vec![f64::NAN; n];
            let xax = system.apply_dot(&x, &mut y);
            let mut expected_xax = 0.0;
            for i in 0..n {
                let yi: f64 = (0..n).map(|j| a[i][j] * x[j]).sum();
                assert!((y[i] - yi).abs() < 1e-12, "row {i}: {} vs {yi}", y[i]);
                expected_xax += x[i] * yi;
            }
            assert!((xax - expected_xax).abs() < 1e-12);
            let mut d = vec![0.0; n];
            system.diagonal(&mut d);
            for i in 0..n {
                assert!((d[i] - a[i][i]).abs() < 1e-12);
            }
            // CG solves it to its tolerance.
            let b: Vec<f64> = (0..n).map(|i| 1.0 + i as f64).collect();
            let mut solution = vec![0.0; n];
            let used = conjugate_gradient(
                &system,
                &b,
                &mut solution,
                1e-12,
                100,
                &mut Workspace::default(),
            );
            assert!(used > 0 && used < 100);
            for i in 0..n {
                let ax: f64 = (0..n).map(|j| a[i][j] * solution[j]).sum();
                assert!((ax - b[i]).abs() < 1e-9 * b[i], "row {i}: {ax} vs {}", b[i]);
            }
        }
    }
}
