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

use super::skin::SkinWeights;

/// An active contact sample as seen by the solver: skin weights and its `dt·c + dt²·k`.
#[derive(Debug, Clone)]
pub struct ContactRow {
    /// Skin weights of the sample.
    pub weights: SkinWeights,
    /// Coefficient of `w·wᵀ` in the system matrix.
    pub coef: f64,
}

/// The system matrix, applied without being formed.
pub struct System<'a> {
    /// Diagonal part: masses, laws, ground links (already scaled by dt).
    pub diag: &'a [f64],
    /// Neighbour edges `(i, j, weight)`.
    pub edges: &'a [(usize, usize, f64)],
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
        for ((y, d), x) in y.iter_mut().zip(self.diag).zip(x) {
            *y = d * x;
        }
        for &(i, j, w) in self.edges {
            let f = self.edge_coef * w * (x[i] - x[j]);
            y[i] += f;
            y[j] -= f;
        }
        if let Some((area, coef)) = self.volume {
            let s: f64 = area.iter().zip(x).map(|(a, x)| a * x).sum::<f64>() * coef;
            for (y, a) in y.iter_mut().zip(area) {
                *y += s * a;
            }
        }
        for row in self.contacts {
            let s: f64 = row.weights.iter().map(|&(i, w)| w * x[i]).sum::<f64>() * row.coef;
            for &(i, w) in &row.weights {
                y[i] += s * w;
            }
        }
    }

    /// The diagonal of `A` (for the Jacobi preconditioner).
    pub fn diagonal(&self, out: &mut [f64]) {
        out.copy_from_slice(self.diag);
        for &(i, j, w) in self.edges {
            out[i] += self.edge_coef * w;
            out[j] += self.edge_coef * w;
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

/// Scratch vectors reused across steps (no allocation per step).
#[derive(Debug, Clone, Default)]
pub struct Workspace {
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    ap: Vec<f64>,
    precond: Vec<f64>,
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
    for v in [&mut ws.r, &mut ws.z, &mut ws.p, &mut ws.ap, &mut ws.precond] {
        v.resize(n, 0.0);
    }
    system.diagonal(&mut ws.precond);
    system.apply(x, &mut ws.ap);
    for (((r, z), p), (b, (ap, d))) in
        ws.r.iter_mut()
            .zip(ws.z.iter_mut())
            .zip(ws.p.iter_mut())
            .zip(b.iter().zip(ws.ap.iter().zip(&ws.precond)))
    {
        *r = b - ap;
        *z = *r / d;
        *p = *z;
    }
    let b_norm = b.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300);
    let mut rz: f64 = ws.r.iter().zip(&ws.z).map(|(r, z)| r * z).sum();
    for iteration in 0..max_iterations {
        let r_norm = ws.r.iter().map(|v| v * v).sum::<f64>().sqrt();
        if r_norm <= tolerance * b_norm {
            return iteration;
        }
        system.apply(&ws.p, &mut ws.ap);
        let pap: f64 = ws.p.iter().zip(&ws.ap).map(|(p, a)| p * a).sum();
        if pap <= 0.0 {
            return iteration;
        }
        let alpha = rz / pap;
        for ((x, p), ((r, ap), (z, d))) in x.iter_mut().zip(&ws.p).zip(
            ws.r.iter_mut()
                .zip(&ws.ap)
                .zip(ws.z.iter_mut().zip(&ws.precond)),
        ) {
            *x += alpha * p;
            *r -= alpha * ap;
            *z = *r / d;
        }
        let rz_next: f64 = ws.r.iter().zip(&ws.z).map(|(r, z)| r * z).sum();
        let beta = rz_next / rz;
        rz = rz_next;
        for i in 0..n {
            ws.p[i] = ws.z[i] + beta * ws.p[i];
        }
    }
    max_iterations
}
