//! Viscoelastic relaxation of the whole elastic structure (`relaxation`,
//! `second_relaxation`).
//!
//! Every linear elastic element of the torso — the particle springs, the neighbour
//! coupling, the ground links and the volume term — carries a Maxwell branch of `ratio`
//! times its own stiffness with the branch's time constant `τ`. With one relaxation
//! function shared by all elements, the correspondence principle says the body relaxes as
//! each element does: a probe pushed to depth δ and held feels `K·δ·(1 + Σ ratio·e^{−t/τ})`,
//! `K` the structure's stiffness under the probe, so `ratio` means at the probe what it
//! means in the catalogue's point-contact law. (A branch on the particle springs alone —
//! the form before — left the coupling and the volume term unrelaxed: the body's
//! relaxation was then not of the catalogue's form at any ratio, and an independent
//! two-branch body came out "unexplained".)
//!
//! Branch `b` keeps one dashpot state per particle, `ẋ_b = (u − x_b)/τ_b`; its force is
//! `−ratio_b·K·(u − x_b)` with `K` the linear elastic operator. In the implicit step the
//! dashpots are held, so the branches stiffen the system by `Σ ratio_b·K` (a constant
//! scale of the elastic terms, which the cached factor keeps) and add `K·Σ ratio_b·x_b` to
//! the right-hand side; the states advance exactly for the step's end displacement.
//! Nonlinear springs (`exponent`) relax with their linear part.

use super::tissue_laws::Relaxation;

/// One Maxwell branch over the whole structure.
#[derive(Debug, Clone)]
struct Branch {
    ratio: f64,
    tau: f64,
    /// Dashpot positions, one per particle \[m\].
    x: Vec<f64>,
}

/// The relaxation branches of a torso (see the module docs).
#[derive(Debug, Clone)]
pub struct StructuralRelaxation {
    branches: Vec<Branch>,
    /// `Σ ratio_b·(u − x_b)` of the current step \[m\].
    lag: Vec<f64>,
}

impl StructuralRelaxation {
    /// The branches for `n` particles at rest, or `None` when there are none.
    pub fn new<'a>(params: impl IntoIterator<Item = &'a Relaxation>, n: usize) -> Option<Self> {
        let branches: Vec<Branch> = params
            .into_iter()
            .filter(|r| r.ratio > 0.0)
            .map(|r| Branch {
                ratio: r.ratio,
                tau: r.tau_s,
                x: vec![0.0; n],
            })
            .collect();
        (!branches.is_empty()).then(|| Self {
            branches,
            lag: vec![0.0; n],
        })
    }

    /// `Σ ratio_b`: how much stiffer the structure is before it relaxes.
    pub fn total_ratio(&self) -> f64 {
        self.branches.iter().map(|b| b.ratio).sum()
    }

    /// `Σ ratio_b·(u − x_b)` for the displacements `u` (the branches' stretch, in the
    /// units of `u`, weighted by their ratios).
    pub fn lag(&mut self, u: &[f64]) -> &[f64] {
        self.lag.fill(0.0);
        for b in &self.branches {
            for ((lag, u), x) in self.lag.iter_mut().zip(u).zip(&b.x) {
                *lag += b.ratio * (u - x);
            }
        }
        &self.lag
    }

    /// Advance the dashpots over a step of `dt` that ended at displacements `u` (exact
    /// for `u` held over the step).
    pub fn advance(&mut self, u: &[f64], dt: f64) {
        for b in &mut self.branches {
            let decay = (-dt / b.tau).exp();
            for (x, u) in b.x.iter_mut().zip(u) {
                *x = u + (*x - u) * decay;
            }
        }
    }

    /// Relax every branch at displacements `u` (a state set from outside starts relaxed).
    pub fn relax_at(&mut self, u: &[f64]) {
        for b in &mut self.branches {
            b.x.copy_from_slice(u);
        }
    }
}
